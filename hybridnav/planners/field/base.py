"""Reactive planners that command a velocity every control cycle (potential fields and kin).

A :class:`FieldPlanner` computes, batched over the active robots, a desired velocity from the
robots' positions, goals and the world at the current time; each robot's model turns it into a
target (:meth:`hybridnav.models.Model.carrot`) and :func:`hybridnav.planners.simulate.simulate`
does the rest. Unicycle robots run the rate-limited heading controller at constant ``speed`` (the
EFFC paper's TurtleBot3: heading change at most ``max_turn`` per control cycle).
"""

from __future__ import annotations

import copy
import logging
import math
import time
from abc import abstractmethod
from typing import Any, ClassVar

import numpy as np

from hybridnav.params import check_seed
from hybridnav.planners.base import Param, Planner
from hybridnav.planners.field.sensing import check_sensor, sensor_notes
from hybridnav.planners.simulate import Simulation, model_groups, simulate
from hybridnav.results import Result

__all__ = ["FieldPlanner"]

log = logging.getLogger(__name__)

COMMON = {
    "speed": Param(0.1, "robot speed along the field (units/s; unicycles: constant speed)",
                   lo=0.0, lo_open=True),
    "max_turn": Param(math.pi / 4, "unicycles: largest heading change per control cycle (rad)",
                      lo=0.0, lo_open=True, hi=math.pi),
    "stuck_window": Param(10.0, "seconds without leaving a small disk that count as stuck "
                                "(0: off)", lo=0.0),
    "stuck_radius": Param(2.0, "that disk's radius, in goal radii", lo=0.0),
    "safety_margin": Param(0.0, "unicycles: room (beyond the robot radius) the escape-circle "
                                "safety filter keeps; 0: off (hybridnav.planners.field.safety)",
                           lo=0.0),
    "scale": Param(0.0, "length scale of the defaults of speed and the length gains (0: the "
                        "scenario's: its robots' median radius / 0.1 m, the EFFC paper's "
                        "robot; 1: the declared defaults as written)", lo=0.0),
}

#: the EFFC paper's robot radius (m): the defaults are written for it
REFERENCE_RADIUS = 0.1


class FieldPlanner(Planner):
    """Base of the potential-field planners: ``velocity(...)`` each cycle, batched over robots."""

    parameters: ClassVar[dict[str, Param]] = dict(COMMON)
    #: parameters whose defaults are lengths (exponent 1: speed, distances) or carry other
    #: powers of length (APF's repulsive gain: 4), scaled by ``scale ** exponent`` unless set
    scaled: ClassVar[dict[str, int]] = {"speed": 1, "safety_margin": 1}
    #: the units of the signals the planner traces (``signals.png``'s axes): ``"rad"``, ``""``
    #: (dimensionless), ``"length"`` (the scenario's length unit); see
    #: :mod:`hybridnav.plotting.labels`
    signal_units: ClassVar[dict[str, str]] = {}

    def __init__(self, **params: Any) -> None:
        super().__init__(**params)
        if "sensor" in self.parameters:          # the planners that read a sensor (sensing.py)
            check_sensor(self.name, self.values)

    def _warn_unfiltered(self, scenario, models) -> None:
        """A safety margin the filter cannot apply (robots without the constant-speed heading
        controller) is said, not silently ignored."""
        if self.values["safety_margin"] > 0:
            names = [r.name for r, m in zip(scenario.robots, models)
                     if getattr(m, "options", {}).get("controller") != "heading"]
            if names:
                log.warning("%s: safety_margin %g applies to heading-controlled unicycles only; "
                            "robots %s run without the filter (other robots are not obstacles "
                            "to it either)", scenario.name, self.values["safety_margin"],
                            ", ".join(names))

    def _filter(self, sim: Simulation, V: np.ndarray, groups) -> None:
        """The escape-circle safety filter on the heading-controlled robots' commands (in place;
        the world's obstacles and border, at the current time)."""
        from hybridnav.planners.field.safety import escape_filter

        world = sim.scenario.world

        def clearance(Q, rows):
            return np.minimum(world.clearance(Q, t=sim.t), world.border_clearance(Q))

        for model, members in groups:
            act = members[sim.active[members]]
            if not len(act) or getattr(model, "options", {}).get("controller") != "heading":
                continue
            X = np.array([sim.X[i] for i in act])
            # each robot's own radius: a group shares a model, not a footprint
            V[act], _ = escape_filter(
                X, V[act], speed=self.values["speed"], dt=sim.scenario.dt,
                max_turn=self.values["max_turn"], margin=self.values["safety_margin"],
                radius=np.array([sim.models[i].radius for i in act]), clearance=clearance)

    def scale_for(self, scenario) -> float:
        """The length scale of this run: ``scale`` when set, else the scenario's robots' median
        radius over the EFFC paper's 0.1 m (1 on the paper's worlds: its defaults unchanged)."""
        if self.values["scale"] > 0:
            return float(self.values["scale"])
        radii = [float(r.radius) for r in scenario.robots]
        s = float(np.median(radii)) / REFERENCE_RADIUS if radii else 1.0
        return s if math.isfinite(s) and s > 0 else 1.0    # point robots: the defaults as written

    def scaled_values(self, scenario) -> dict[str, Any]:
        """The values a run on ``scenario`` uses: defaults of :attr:`scaled` parameters times
        ``scale ** p`` (values the user or the profile set stay as they are); ``scale`` holds
        the factor."""
        s = self.scale_for(scenario)
        values = dict(self.values)
        for key, power in self.scaled.items():
            if key not in self.given:
                values[key] = self.values[key] * s ** power
        values["scale"] = s
        return values

    def prepare(self, scenario, rng: np.random.Generator) -> Any:
        """Work done once per run before the loop (a harmonic field, tuned gains, ...)."""
        return None

    @abstractmethod
    def velocity(self, state: Any, sim: Simulation, idx: np.ndarray, P: np.ndarray,
                 goals: np.ndarray) -> np.ndarray:
        """Desired velocities ``(len(idx), 2)`` of the active robots ``idx`` at ``P``.

        May call ``sim.stop(i, "stuck")`` for a robot whose field vanishes.
        """

    def trace(self, sim: Simulation, idx: np.ndarray, **signals: np.ndarray) -> None:
        """Record per-robot signals of this cycle (in the run's ``sim.notes``; the result carries
        them as the extras ``signals_<robot>``, plotted and written by ``hybridnav run``)."""
        store = sim.notes.setdefault("signals", {})
        for j, i in enumerate(idx):
            rec = store.setdefault(sim.scenario.robots[i].name, {"t": []})
            rec["t"].append(sim.t)
            for key, values in signals.items():
                rec.setdefault(key, []).append(float(values[j]))

    def extras(self, scenario, state: Any) -> dict[str, Any]:
        """What the run's offline work leaves for diagnostics (a field, a search log), as
        :attr:`hybridnav.results.Result.extras` entries; default none."""
        return {}

    def diagnostics(self, scenario, result: Result) -> dict[str, Any]:
        """``signals.png``: the traced signals of every robot over time."""
        from hybridnav.plotting import plot_signals

        fig = plot_signals(result, units=self.signal_units, length=scenario.units)
        return {} if fig is None else {"signals.png": fig}

    def model_overrides(self, robot) -> dict[str, Any]:
        """Model options for a robot (models with a heading controller, the unicycle: that
        controller at ``speed``)."""
        from hybridnav.models import MODELS

        if "heading_control" in MODELS[robot.model].capabilities:
            return {"controller": "heading", "speed": self.values["speed"],
                    "max_turn": self.values["max_turn"]}
        return {}

    def run(self, scenario, seed: int | None = None) -> Result:
        self.check_scenario(scenario)
        seed = check_seed(seed)
        # the run works on a copy holding the scenario's values: the planner itself is not
        # changed by a run (one instance runs scenarios of any scale alike)
        run = copy.copy(self)
        run.values = self.scaled_values(scenario)
        return run._run(scenario, seed)

    def _run(self, scenario, seed: int | None) -> Result:
        rng = np.random.default_rng(seed)
        tic = time.perf_counter()
        state = self.prepare(scenario, rng)
        prep = time.perf_counter() - tic
        models = [scenario.model(r, **self.model_overrides(r)) for r in scenario.robots]
        self._warn_unfiltered(scenario, models)
        speed = self.values["speed"]
        last = np.zeros((len(models), 2))       # the last non-zero command of each robot
        groups = model_groups(models)

        def controller(sim: Simulation) -> np.ndarray:
            T = np.full((sim.n, 2), np.nan)
            idx = np.flatnonzero(sim.active)
            P = sim.positions[idx]
            V = np.asarray(self.velocity(state, sim, idx, P, sim.goals()[idx]), dtype=float)
            norm = np.hypot(V[:, 0], V[:, 1])
            V = V * (speed / np.where(norm > 0, norm, 1.0))[:, None]
            # a resultant of exactly zero (balanced forces) keeps the previous command
            zero = ~(norm > 0)
            V[zero] = last[idx[zero]]
            last[idx[~zero]] = V[~zero]
            Vall = np.zeros((sim.n, 2))
            Vall[idx] = V
            if self.values["safety_margin"] > 0:
                self._filter(sim, Vall, groups)
            for model, members in groups:          # one carrot call per model group
                act = members[sim.active[members]]
                if len(act):
                    T[act] = model.carrot(np.array([sim.X[i] for i in act]), Vall[act])
            return T

        goal_r = np.array([r.goal_radius for r in scenario.robots])
        robots, sim = simulate(scenario, models, controller,
                               stuck_window=self.values["stuck_window"],
                               stuck_radius=self.values["stuck_radius"] * goal_r,
                               notes=sensor_notes(self.values, seed))
        for r in robots:   # offline work (a field solve, a gain search) is part of the cost
            r.compute_time += prep / len(robots)
        extras = {f"signals_{name}": rec for name, rec in sim.notes.get("signals", {}).items()}
        extras.update(self.extras(scenario, state))
        return Result(scenario=scenario.name, planner=self.name, params=self.describe(),
                      seed=seed, robots=robots, extras=extras)
