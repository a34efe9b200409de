"""A classic reactive Mamdani steering controller: ``fuzzy-steer``.

Each control cycle, per robot (batched over robots), the fuzzy system reads four inputs:

* ``left``, ``front``, ``right``: the free distance (from the robot's footprint, capped at
  ``sensor_range``) to the nearest obstacle whose nearest surface point lies in that sector of
  the robot's heading — ``front`` within ``front_angle`` (45 degrees) either side, ``left`` and ``right`` from
  there to 90 degrees (a range sensor ring reduced to three sectors; obstacles behind are
  ignored);
* ``bearing``: the direction to the goal relative to the heading (rad, in [-pi, pi], positive
  to the left);

and its output ``turn`` (rad, positive to the left) is the commanded heading change: the
unicycle turns towards ``heading + turn`` by at most ``max_turn`` per cycle at constant
``speed``. The built-in start system ``steer-7rule`` holds seven hand-written rules (go for the
goal when the way ahead is free; turn towards the freer side when it is not); it is tunable by
the same job machinery as EFFC (``[cost] planner = "fuzzy-steer"``).
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from hybridnav.errors import HybridnavError
from hybridnav.planners.base import Param
from hybridnav.planners.field.base import COMMON, FieldPlanner
from hybridnav.planners.field.lockstep import LockstepResult, lockstep_field
from hybridnav.planners.simulate import Simulation

__all__ = ["FuzzySteer", "steer_inputs", "steer_lockstep"]

INPUTS = ("left", "front", "right", "bearing")


def _wrap(a: np.ndarray) -> np.ndarray:
    return np.arctan2(np.sin(a), np.cos(a))


def steer_inputs(P: np.ndarray, theta: np.ndarray, goals: np.ndarray, D: np.ndarray,
                 near: np.ndarray, radius, sensor_range: float, front_angle: float
                 ) -> dict[str, np.ndarray]:
    """The four inputs at positions ``P`` (N, 2) with headings ``theta`` (N,), from every
    obstacle's signed clearance ``D`` (N, K) and nearest point ``near`` (N, K, 2)."""
    n = len(P)
    sensor = float(sensor_range)
    if D.shape[1]:
        rel = _wrap(np.arctan2(near[..., 1] - P[:, None, 1], near[..., 0] - P[:, None, 0])
                    - theta[:, None])
        d = np.clip(D - np.asarray(radius, dtype=float).reshape(-1, 1)
                    if np.ndim(radius) else D - float(radius), 0.0, sensor)
        d = np.where(np.isfinite(D), d, sensor)
        rel = np.where(np.isfinite(rel), rel, math.pi)            # padding: behind, ignored
        front = np.abs(rel) <= front_angle
        left = (rel > front_angle) & (rel <= math.pi / 2)
        right = (rel < -front_angle) & (rel >= -math.pi / 2)
        out = {name: np.min(np.where(m, d, sensor), axis=1)
               for name, m in (("left", left), ("front", front), ("right", right))}
    else:
        out = {name: np.full(n, sensor) for name in ("left", "front", "right")}
    to_goal = goals - P
    out["bearing"] = _wrap(np.arctan2(to_goal[:, 1], to_goal[:, 0]) - theta)
    return out


def steer_direction(theta: np.ndarray, turn: np.ndarray) -> np.ndarray:
    """Unit vectors of the commanded headings ``theta + turn`` (N, 2)."""
    a = theta + turn
    return np.column_stack([np.cos(a), np.sin(a)])


def steer_lockstep(st, family, tables, n_members: int, planner: dict[str, Any], *,
                   repeats: int = 1, noise: np.ndarray | None = None,
                   record_paths: bool = False) -> LockstepResult:
    """``n_members`` steering controllers on every world of ``st`` in one lockstep batch
    (:func:`hybridnav.planners.field.effc.effc_lockstep`'s contract; of the noise only the
    heading channel applies: it rotates the command)."""
    scenarios = st.scenarios
    dt = scenarios[0].dt
    radius = st.radius
    sensor = planner.get("sensor_range", 1.0)
    front_angle = planner.get("front_angle", math.pi / 4)
    last = None if noise is None else noise.shape[3] - 1

    def field(env, members, X, goals, t):
        P, theta = X[:, :2], X[:, 2]
        D, near = st.stack.nearest_each(P, env, t)
        inputs = steer_inputs(P, theta, goals, D, near, radius[env], sensor, front_angle)
        turn = family.evaluate(tables, members // repeats, inputs)
        if noise is not None:
            turn = turn + noise[0, env, members, min(int(round(t / dt)), last)]
        return steer_direction(theta, turn)

    overrides = {"controller": "heading", "speed": planner["speed"],
                 "max_turn": planner["max_turn"]}
    return lockstep_field(scenarios, n_members, field, model_overrides=overrides,
                          speed=planner["speed"], stuck_window=planner["stuck_window"],
                          stuck_radius=planner["stuck_radius"], record_paths=record_paths,
                          stack=st.stack, field_state=True,
                          safety={"margin": planner.get("safety_margin", 0.0),
                                  "max_turn": planner["max_turn"]})


class FuzzySteer(FieldPlanner):
    """Reactive fuzzy steering: sector ranges and the goal bearing in, a heading change out."""

    name = "fuzzy-steer"
    description = "reactive Mamdani steering: left/front/right ranges and goal bearing -> turn"
    parameters: ClassVar[dict[str, Param]] = {
        "fis": Param("steer-7rule", "fuzzy system with inputs left, front, right, bearing and "
                                    "a heading-change output (rad): a built-in name or a "
                                    ".json, .fll or .fis file"),
        "sensor_range": Param(1.0, "sector ranges are capped at this distance (m)", lo=0.0,
                              lo_open=True),
        "front_angle": Param(math.pi / 4, "the front sector's half width (rad)", lo=0.0,
                             lo_open=True, hi=math.pi / 2),
        **COMMON,
    }
    scaled: ClassVar[dict[str, int]] = {**FieldPlanner.scaled, "sensor_range": 1}
    #: robots with a heading to steer (the unicycle)
    drives: ClassVar[tuple[frozenset[str], ...]] = (frozenset({"robot", "heading_control"}),)
    #: the fuzzy inputs this planner provides (what a tuned system must take)
    fuzzy_inputs: ClassVar[tuple[str, ...]] = INPUTS
    #: the units of the fuzzy variables (ranges capped at the sensor range in metres, angles)
    fuzzy_units: ClassVar[dict[str, str]] = {"left": "m", "front": "m", "right": "m",
                                             "bearing": "rad", "turn": "rad"}
    #: the traced signals (the range in the scenario's unit)
    signal_units: ClassVar[dict[str, str]] = {"turn": "rad", "front": "length", "bearing": "rad"}
    #: many controllers on many worlds in one batch (what the tuner simulates)
    lockstep = staticmethod(steer_lockstep)

    def __init__(self, **params: Any) -> None:
        from hybridnav import fuzzy

        system = params.get("fis")
        if isinstance(system, fuzzy.FuzzySystem):
            params["fis"] = system.name
        super().__init__(**params)
        if not isinstance(system, fuzzy.FuzzySystem):
            system = fuzzy.load_any(self.values["fis"])
        if set(system.input_names) != set(INPUTS):
            raise HybridnavError(
                f"planner fuzzy-steer: fis: expected a fuzzy system with the inputs "
                f"{', '.join(INPUTS)}, {system.name!r} has {', '.join(system.input_names)}")
        self.fis = system

    def velocity(self, state, sim: Simulation, idx, P, goals):
        theta = np.array([sim.X[i][2] for i in idx], dtype=float)
        radius = np.array([sim.models[i].radius for i in idx])
        D, near = sim.scenario.world.nearest_each(P, t=sim.t)
        inputs = steer_inputs(P, theta, goals, D, near, radius, self.values["sensor_range"],
                              self.values["front_angle"])
        turn = self.fis.evaluate(**inputs)
        self.trace(sim, idx, turn=turn, front=inputs["front"], bearing=inputs["bearing"])
        return steer_direction(theta, turn)

    def describe(self):
        return dict(self.values)
