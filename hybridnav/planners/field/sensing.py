"""How a reactive planner learns where the obstacles are: exact geometry, or a simulated lidar.

The planners that steer by the nearest obstacle (EFFC, APF and PBPF's APF) declare
:data:`SENSOR` among their parameters and ask :func:`perceive` for the world of each control
cycle. ``sensor = "exact"`` (the default) is the scenario's world itself, so the run is exactly
what it was without the option. ``sensor = "lidar"`` is one scan per cycle of a
:class:`~hybridnav.world.lidar.Lidar` from every active robot (``lidar_beams`` beams, the first
along the robot's heading, returns within ``[lidar_min_range, lidar_max_range]``, Gaussian range
noise of standard deviation ``sensor_noise``; the defaults are a TurtleBot3's LDS-01), and the
planner's nearest obstacle point is the nearest return (per obstacle for APF). The noise comes
from a generator of its own seeded from the run's seed (:func:`sensor_rng`), so a run is
reproducible and the planner's other random draws are not shifted. The lengths are in the
scenario's units (the LDS-01's are metres) and are not scaled with the robot.

What still uses the exact geometry with the lidar on: the collision and clearance checks of the
simulation (the truth the metrics report), the escape-circle safety filter (``safety_margin``),
and PBPF's offline gain search (its lockstep runs), which sees the map; HAPF has no sensor (its
field is solved on the known map).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hybridnav.errors import HybridnavError
from hybridnav.params import Param

__all__ = ["SENSOR", "check_sensor", "perceive", "sensor_notes", "sensor_rng"]

SENSOR: dict[str, Param] = {
    "sensor": Param("exact", "where the nearest obstacle comes from: exact (the map's geometry) "
                             "or lidar (a simulated 2-D laser scan each control cycle)",
                    choices=("exact", "lidar")),
    "sensor_noise": Param(0.0, "lidar: standard deviation of the Gaussian range noise "
                               "(scenario units; 0: none)", lo=0.0),
    "lidar_beams": Param(360, "lidar: beams over a full turn (LDS-01: 360, 1 degree apart)",
                         lo=4, hi=100_000),
    "lidar_min_range": Param(0.12, "lidar: shortest range it returns (LDS-01: 0.12 m)", lo=0.0),
    "lidar_max_range": Param(3.5, "lidar: longest range it returns (LDS-01: 3.5 m)", lo=0.0,
                             lo_open=True),
}

#: the spawn key of the sensor's random stream under the run's seed
_STREAM = 0x1DA


def check_sensor(name: str, values: dict[str, Any]) -> None:
    """What one declaration cannot say: lidar settings without the lidar, an empty range.

    Raises
    ------
    HybridnavError
        ``sensor_noise > 0`` (or other lidar settings changed) with ``sensor = "exact"``, or
        ``lidar_min_range >= lidar_max_range``.
    """
    if values["sensor"] != "lidar":
        if values["sensor_noise"] > 0:
            raise HybridnavError(
                f"planner {name}: sensor_noise: expected 0 with sensor = exact (the noise is the "
                f"lidar's: set sensor = lidar), got {values['sensor_noise']!r}")
        return
    if not values["lidar_min_range"] < values["lidar_max_range"]:
        raise HybridnavError(
            f"planner {name}: lidar_min_range: expected less than lidar_max_range "
            f"({values['lidar_max_range']!r}), got {values['lidar_min_range']!r}")


def sensor_rng(seed: int | None) -> np.random.Generator:
    """The generator of a run's sensor noise: its own stream under the run's ``seed``."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(_STREAM,)))


def sensor_notes(values: dict[str, Any], seed: int | None) -> dict[str, Any]:
    """What a run keeps for :func:`perceive` (in :attr:`Simulation.notes`): nothing for the exact
    sensor, else the lidar and its generator."""
    if values.get("sensor", "exact") != "lidar":
        return {}
    from hybridnav.world.lidar import Lidar

    lidar = Lidar(beams=int(values["lidar_beams"]), min_range=float(values["lidar_min_range"]),
                  max_range=float(values["lidar_max_range"]), noise=float(values["sensor_noise"]))
    return {"lidar": lidar, "lidar_rng": sensor_rng(seed)}


def perceive(sim, idx: np.ndarray, P: np.ndarray):
    """The world the robots ``idx`` (at ``P``) perceive this cycle: the scenario's world, or one
    lidar scan from each (a :class:`~hybridnav.world.lidar.SensedWorld` answering ``nearest``
    and ``nearest_each`` at ``P``)."""
    lidar = sim.notes.get("lidar")
    world = sim.scenario.world
    if lidar is None:
        return world
    headings = np.array([sim.X[i][sim.models[i].state_names.index("theta")]
                         if "theta" in sim.models[i].state_names else 0.0 for i in idx])
    return lidar.scan(world, P, headings, sim.t, sim.notes["lidar_rng"])
