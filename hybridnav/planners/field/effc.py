"""Evolutionary fuzzy force control (EFFC; Golkhatib, Shahmansoorian & Davoudi 2025).

Each control cycle, per robot (batched over robots):

* ``F_att``: unit vector from the robot to its target; ``F_rep``: unit vector from the nearest
  obstacle point to the robot (the paper's Section 3);
* the fuzzy system's inputs: ``dtheta = |direction to target - direction to nearest obstacle|``
  (wrapped to [0, pi]; the system clips it to its range) and ``alpha = d_obstacle / d_target``,
  with ``d_obstacle`` measured from the robot's footprint; a system may also take
  ``clearance = d_obstacle`` itself (absolute: a margin it can keep whatever the goal distance);
* ``w = FIS(dtheta, alpha)`` through the compiled batched evaluator, and
  ``F_w = w F_rep + (1 - w) F_att`` (eq. 8);
* the unicycle turns towards ``F_w`` by at most ``max_turn`` (pi/4) per cycle at constant
  ``speed`` (0.1 m/s), eq. 9.

Any :class:`hybridnav.fuzzy.FuzzySystem` with inputs ``dtheta`` and ``alpha`` can be plugged in
(``fis=`` a built-in name, a JSON file, or a ``FuzzySystem``); the default is the paper's reduced
2-rule system. Without obstacles ``F_w = F_att``.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from hybridnav.errors import HybridnavError
from hybridnav.planners.base import Param
from hybridnav.planners.field.base import COMMON, FieldPlanner
from hybridnav.planners.field.lockstep import LockstepResult, lockstep_field, prepare
from hybridnav.planners.field.sensing import SENSOR, perceive
from hybridnav.planners.simulate import Simulation

__all__ = ["EFFC", "effc_clearance", "effc_inputs", "effc_inputs_from", "effc_force",
           "effc_lockstep"]


def effc_inputs(world, P: np.ndarray, goals: np.ndarray, radius, t: float):
    """The fuzzy inputs and the two unit forces at the points ``P`` (N, 2).

    Returns
    -------
    dtheta, alpha : ndarray, shape (N,)
    f_att, f_rep : ndarray, shape (N, 2)
    """
    n = len(P)
    if not world.obstacles:
        clear, near = np.full(n, np.inf), np.full((n, 2), np.nan)
    else:
        clear, near, _ = world.nearest(P, t=t)
    return effc_inputs_from(P, goals, clear, near, radius)


def effc_inputs_from(P: np.ndarray, goals: np.ndarray, clear: np.ndarray, near: np.ndarray,
                     radius):
    """:func:`effc_inputs` from the nearest obstacle's signed clearance ``clear`` (N,) and
    surface point ``near`` (N, 2); rows with ``clear = inf`` (no obstacle) get ``dtheta = pi``,
    ``alpha = inf`` and no repulsion."""
    to_goal = goals - P
    d_goal = np.hypot(to_goal[:, 0], to_goal[:, 1])
    f_att = to_goal / np.where(d_goal > 0, d_goal, 1.0)[:, None]
    none = np.isinf(clear)
    if none.any():
        near = np.where(none[:, None], P, near)
    away = P - near
    d_near = np.hypot(away[:, 0], away[:, 1])
    f_rep = away / np.where(d_near > 0, d_near, 1.0)[:, None]
    inside = clear < 0                       # inside an obstacle: push out through the surface
    f_rep[inside] *= -1.0
    ang = np.arctan2(to_goal[:, 1], to_goal[:, 0]) - np.arctan2(-f_rep[:, 1], -f_rep[:, 0])
    dtheta = np.abs(np.arctan2(np.sin(ang), np.cos(ang)))
    d_obs = np.maximum(clear - np.asarray(radius, dtype=float), 0.0)
    alpha = d_obs / np.where(d_goal > 0, d_goal, np.finfo(float).tiny)
    if none.any():
        dtheta[none], alpha[none], f_rep[none] = np.pi, np.inf, 0.0
    return dtheta, alpha, f_att, f_rep


def effc_clearance(clear: np.ndarray, radius) -> np.ndarray:
    """The optional fuzzy input ``clearance``: the distance from the robot's footprint to the
    nearest obstacle, ``max(clear - radius, 0)`` (``inf`` without obstacles) — the numerator of
    ``alpha``, absolute instead of relative to the goal distance, so that a system can keep a
    margin however far the goal is."""
    clear = np.asarray(clear, dtype=float)
    return np.where(np.isinf(clear), np.inf,
                    np.maximum(clear - np.asarray(radius, dtype=float), 0.0))


def effc_force(w: np.ndarray, f_att: np.ndarray, f_rep: np.ndarray) -> np.ndarray:
    """``F_w = w F_rep + (1 - w) F_att`` (rows)."""
    w = np.asarray(w, dtype=float)[:, None]
    return w * f_rep + (1.0 - w) * f_att


def effc_lockstep(st, family, tables, n_members: int,
                  planner: dict[str, Any], *, repeats: int = 1, noise: np.ndarray | None = None,
                  record_paths: bool = False) -> LockstepResult:
    """``n_members`` EFFC controllers on every world of ``st``, in one lockstep batch.

    ``st`` holds ``scenarios``, their packed obstacles ``stack``
    (:class:`~hybridnav.planners.field.worldstack.WorldStack`) and robot ``radius`` per world.

    Member ``m`` uses the fuzzy system ``m // repeats`` of ``tables`` (a ``family`` table set);
    ``noise`` (``(3, E, n_members, steps)``: heading, ``dtheta``, relative ``alpha``) perturbs
    each cycle. ``planner`` holds ``speed``, ``max_turn``, ``stuck_window`` and
    ``stuck_radius`` (and optionally ``safety_margin``: the escape-circle safety filter). Without noise this is exactly what the ``effc`` planner does, run by run.
    """
    scenarios = st.scenarios
    dt = scenarios[0].dt
    radius = st.radius
    last = None if noise is None else noise.shape[3] - 1
    overrides = {"controller": "heading", "speed": planner["speed"],
                 "max_turn": planner["max_turn"]}
    batch = prepare(scenarios, n_members, overrides, st.stack)
    from hybridnav.native.lockstep import effc_run

    res = effc_run(batch, family, tables, planner, repeats=repeats, noise=noise, radius=radius,
                   record_paths=record_paths)
    if res is not None:                  # the compiled control cycle
        return res

    wants_clearance = "clearance" in [v.name for v in family.inputs]

    def field(env, members, P, goals, t):
        clear, near = st.stack.nearest(P, env, t)
        dtheta, alpha, f_att, f_rep = effc_inputs_from(P, goals, clear, near, radius[env])
        inputs = {"dtheta": dtheta, "alpha": alpha}
        if wants_clearance:
            inputs["clearance"] = effc_clearance(clear, radius[env])
        if noise is not None:
            i = min(int(round(t / dt)), last)
            inputs["dtheta"] = dtheta + noise[1, env, members, i]
            inputs["alpha"] = np.maximum(alpha * (1.0 + noise[2, env, members, i]), 0.0)
            if wants_clearance:          # the same distance sensor as alpha's numerator
                c = inputs["clearance"]
                inputs["clearance"] = np.where(
                    np.isinf(c), c, np.maximum(c * (1.0 + noise[2, env, members, i]), 0.0))
        w = family.evaluate(tables, members // repeats, inputs)
        F = effc_force(w, f_att, f_rep)
        F = np.where(np.isinf(clear)[:, None], f_att, F)     # no obstacle: go to the goal
        if noise is not None:
            ang = noise[0, env, members, i]
            c, s_ = np.cos(ang), np.sin(ang)
            F = np.stack([c * F[:, 0] - s_ * F[:, 1], s_ * F[:, 0] + c * F[:, 1]], axis=1)
        return F

    return lockstep_field(scenarios, n_members, field, model_overrides=overrides,
                          speed=planner["speed"], stuck_window=planner["stuck_window"],
                          stuck_radius=planner["stuck_radius"], record_paths=record_paths,
                          stack=st.stack, safety={"margin": planner.get("safety_margin", 0.0),
                                                  "max_turn": planner["max_turn"]})


class EFFC(FieldPlanner):
    """Potential field whose repulsive/attractive blend weight comes from a fuzzy system."""

    name = "effc"
    description = "evolutionary fuzzy force control: fuzzy-weighted blend of unit APF forces"
    parameters: ClassVar[dict[str, Param]] = {
        "fis": Param("effc-2rule", "fuzzy system: a built-in name, a .json, .fll or .fis file, "
                                   "or an exported .c file (compiled and called: software in "
                                   "the loop)"),
        **COMMON,
        **SENSOR,
    }

    def __init__(self, **params: Any) -> None:
        from hybridnav import fuzzy
        from hybridnav.fuzzy.export.sil import CompiledFIS

        system = params.get("fis")
        if isinstance(system, fuzzy.FuzzySystem):
            params["fis"] = system.name
        elif isinstance(system, CompiledFIS):
            params["fis"] = system.source
        super().__init__(**params)
        if not isinstance(system, (fuzzy.FuzzySystem, CompiledFIS)):
            spec = self.values["fis"]
            system = CompiledFIS(spec) if spec.endswith(".c") else fuzzy.load_any(spec)
        from hybridnav.planners.base import accepts_inputs

        if not accepts_inputs(type(self), system.input_names):
            raise HybridnavError(
                f"planner effc: fis: expected a fuzzy system with the inputs dtheta and alpha "
                f"(and optionally clearance), {system.name!r} has "
                f"{', '.join(system.input_names)}")
        self.fis = system

    #: the fuzzy inputs this planner provides (what a tuned system must take)
    fuzzy_inputs: ClassVar[tuple[str, ...]] = ("dtheta", "alpha")
    #: inputs it also provides to a system that takes them (the footprint's clearance)
    optional_fuzzy_inputs: ClassVar[tuple[str, ...]] = ("clearance",)
    #: the units of the fuzzy variables (the EFFC worlds are in metres; alpha is a ratio of two
    #: distances, w a blend weight)
    fuzzy_units: ClassVar[dict[str, str]] = {"dtheta": "rad", "alpha": "", "clearance": "m",
                                             "w": ""}
    #: the traced signals: the fuzzy inputs and w, the clearance in the scenario's unit
    signal_units: ClassVar[dict[str, str]] = {**fuzzy_units, "clearance": "length"}
    #: many controllers on many worlds in one batch (what the tuner simulates)
    lockstep = staticmethod(effc_lockstep)

    def velocity(self, state, sim: Simulation, idx, P, goals):
        radius = np.array([sim.models[i].radius for i in idx])
        world = perceive(sim, idx, P)
        if not world.obstacles:
            return effc_inputs(world, P, goals, radius, sim.t)[2]
        clear, near, _ = world.nearest(P, t=sim.t)
        dtheta, alpha, f_att, f_rep = effc_inputs_from(P, goals, clear, near, radius)
        inputs = {"dtheta": dtheta, "alpha": alpha}
        if "clearance" in self.fis.input_names:
            inputs["clearance"] = effc_clearance(clear, radius)
        w = self.fis.evaluate(**inputs)
        # (alpha and clearance capped for the plots: the system clips them to its ranges)
        self.trace(sim, idx, w=w, **{k: np.minimum(v, 1e3) for k, v in inputs.items()})
        return effc_force(w, f_att, f_rep)

    def describe(self):
        return {**self.values, "fis": self.values["fis"]}
