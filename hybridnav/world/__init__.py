"""Workspaces, obstacles, robots and scenarios.

This package holds the geometry every planner and model shares:

* obstacle shapes (:class:`Circle`, :class:`Segment`, :class:`Rectangle`, :class:`Polygon`,
  :class:`MovingCircle`) with vectorized signed-distance (``clearance``) and nearest-point queries;
* :class:`World`: a rectangular workspace plus obstacles, with queries vectorized over ``(N, 2)``
  point arrays *and* over obstacles (obstacles are packed into arrays once, at construction);
* :class:`Robot` and :class:`Scenario`, and the TOML loader :func:`load_scenario` with validation
  (:func:`scenario_from_dict`) and its inverse :func:`scenario_to_dict`;
* :class:`WorldGenerator` (:mod:`~hybridnav.world.generator`): seeded random solvable worlds;
* occupancy grids and MovingAI maps in :mod:`hybridnav.world.grid`.

Conventions
-----------
* Points are ``(N, 2)`` float arrays of ``(x, y)``; a single ``(2,)`` point is accepted and treated
  as ``N = 1`` (results are still ``(1,)`` / ``(1, 2)``).
* ``clearance`` is a signed distance: positive outside an obstacle, zero on its surface, negative
  inside. A :class:`Segment` has no inside, so its clearance is the (never negative) distance.
* A disk of radius ``r`` centred at ``p`` *collides* when ``clearance(p) < r``: touching is not a
  collision. Collision queries concern obstacles only; leaving the workspace is a separate question
  (:meth:`World.inside_workspace`, :meth:`World.border_clearance`).
* Moving circles move linearly, ``x(t) = x0 + v cos(heading) t``, ``y(t) = y0 + v sin(heading) t``;
  :class:`World` queries take the time ``t`` (a scalar, or one time per point).
"""
from hybridnav.world.builtin import builtin_data_path
from hybridnav.world.geometry import (
    point_segment_distance,
    points_in_convex_polygon,
    segment_segment_distance,
)
from hybridnav.world.obstacles import (
    OBSTACLE_TYPES,
    Circle,
    MovingCircle,
    Obstacle,
    Polygon,
    Rectangle,
    Segment,
)
from hybridnav.world.scenario import GridSpec, Robot, Scenario
from hybridnav.world.schema import (
    MODEL_NAMES,
    list_scenarios,
    load_scenario,
    scenario_from_dict,
)
from hybridnav.world.generator import WorldGenerator
from hybridnav.world.world import World
from hybridnav.world.writer import (
    save_scenario,
    scenario_to_dict,
    scenario_to_toml,
    toml_dumps,
)

__all__ = [
    "MODEL_NAMES",
    "OBSTACLE_TYPES",
    "Circle",
    "Segment",
    "Rectangle",
    "Polygon",
    "MovingCircle",
    "Obstacle",
    "World",
    "Robot",
    "GridSpec",
    "Scenario",
    "point_segment_distance",
    "segment_segment_distance",
    "points_in_convex_polygon",
    "load_scenario",
    "scenario_from_dict",
    "scenario_to_dict",
    "scenario_to_toml",
    "save_scenario",
    "list_scenarios",
    "builtin_data_path",
    "toml_dumps",
    "WorldGenerator",
]
