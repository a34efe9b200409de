"""Robots and scenarios: what a planner is asked to solve."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from hybridnav.errors import HybridnavError, where
from hybridnav.world.world import World

__all__ = ["GridSpec", "Robot", "Scenario"]


@dataclass(frozen=True)
class Robot:
    """A robot of a scenario.

    Parameters
    ----------
    name : str
        Unique within the scenario.
    model : str
        One of :data:`MODEL_NAMES`.
    start : (float, float)
        Initial position.
    goal : (float, float) or None
        Fixed target; None when the robot follows another robot (``goal_follow``).
    goal_follow : str or None
        Name of another robot whose current position is this robot's (moving) target.
    goal_radius : float
        The goal is reached within this distance (positive).
    radius : float
        Footprint radius (non-negative).
    initial : dict of str to float
        Other initial states by name (e.g. ``theta``); checked by the model layer, not here.
    params : dict of str to float
        Model parameter overrides; checked by the model layer, not here.
    """

    name: str
    model: str
    start: tuple[float, float]
    goal: tuple[float, float] | None = None
    goal_follow: str | None = None
    goal_radius: float = 0.5
    radius: float = 0.5
    initial: dict[str, float] = field(default_factory=dict)
    params: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class GridSpec:
    """How a scenario is turned into an occupancy grid (see :func:`hybridnav.world.grid.build_grid`).

    Parameters
    ----------
    map : str or None
        ``"movingai:NAME"`` (a map shipped in ``hybridnav/scenarios/data``), a path to a MovingAI
        ``.map`` file (relative paths are relative to the scenario file), or None to rasterize the
        world's obstacles.
    resolution : float
        Cell size in workspace units (positive).
    """

    map: str | None = None
    resolution: float = 1.0


@dataclass(frozen=True)
class Scenario:
    """A navigation problem: a world, robots and simulation settings.

    Parameters
    ----------
    name, description, units : str
        ``units`` is a label only (e.g. ``"cm"``, ``"m"``).
    dt : float
        Control and integration step, seconds.
    max_time : float
        Time budget, seconds.
    world : World
    robots : list of Robot
    grid : GridSpec or None
    source : str or None
        File the scenario was read from (not compared by ``==``).
    """

    name: str
    description: str
    units: str
    dt: float
    max_time: float
    world: World
    robots: list[Robot]
    grid: GridSpec | None = None
    source: str | None = field(default=None, compare=False)

    def model(self, robot: str | Robot, **overrides: Any):
        """The kinematic model of a robot, with the scenario's ``dt`` and the robot's parameters.

        ``overrides`` are passed on to :func:`hybridnav.models.get` (e.g. ``jit=False``).
        """
        from hybridnav import models

        r = self.robot(robot) if isinstance(robot, str) else robot
        return models.get(r.model, dt=self.dt, radius=r.radius, **{**r.params, **overrides})

    def robot(self, name: str) -> Robot:
        """The robot called ``name``.

        Raises
        ------
        HybridnavError
            No robot has that name.
        """
        for r in self.robots:
            if r.name == name:
                return r
        raise HybridnavError(
            f"{where(self.source, 'robots')}: no robot named {name!r}; expected one of "
            f"{', '.join(r.name for r in self.robots)}"
        )

    @property
    def max_steps(self) -> int:
        """Number of ``dt`` steps in ``max_time`` (rounded up)."""
        return int(math.ceil(self.max_time / self.dt - 1e-9))
