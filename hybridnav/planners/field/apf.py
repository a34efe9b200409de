"""Artificial potential field (the EFFC paper's eqs. 1-5, after Khatib).

Attractive potential quadratic within ``sigma0`` of the goal and conic beyond it::

    F_att = -xi (q - q_goal)                          if |q - q_goal| <= sigma0
          = -xi sigma0 (q - q_goal) / |q - q_goal|    otherwise

Repulsive force from every obstacle whose nearest surface point is within ``rho0`` (``rho`` is
measured from the robot's footprint, i.e. clearance minus the robot radius)::

    F_rep,i = eta (1/rho - 1/rho0) (1/rho^2) (q - q_obst,i) / rho

The robot moves along ``F_att + sum_i F_rep,i`` at ``speed``. Where that force vanishes (a local
minimum) the robot is ``stuck``; an oscillation in place is caught by the no-progress test.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from hybridnav.planners.base import Param
from hybridnav.planners.field.base import COMMON, FieldPlanner
from hybridnav.planners.field.lockstep import LockstepResult, lockstep_field
from hybridnav.planners.field.sensing import SENSOR, perceive
from hybridnav.planners.simulate import Simulation

__all__ = ["APF", "apf_force", "apf_lockstep"]


def apf_force(world, P: np.ndarray, goals: np.ndarray, radius, t: float, *,
              xi, sigma0, eta, rho0) -> np.ndarray:
    """Total APF force at the points ``P`` (N, 2) for goals (N, 2).

    ``radius`` and the gains are scalars or ``(N,)`` arrays (one set per point: PBPF evaluates a
    population of gains at once).
    """
    xi, sigma0, eta, rho0, radius = (np.broadcast_to(np.asarray(v, dtype=float), (len(P),))
                                     for v in (xi, sigma0, eta, rho0, radius))
    D = P - goals
    dist = np.hypot(D[:, 0], D[:, 1])
    scale = np.where(dist <= sigma0, xi, xi * sigma0 / np.where(dist > 0, dist, 1.0))
    F = -scale[:, None] * D
    if world.obstacles:
        clear, near = world.nearest_each(P, t=t)
        rho = np.maximum(clear - radius[:, None], 1e-9)
        on = rho <= rho0[:, None]
        mag = np.where(on, eta[:, None] * (1.0 / rho - 1.0 / rho0[:, None]) / rho**2, 0.0)
        away = P[:, None, :] - near
        norm = np.hypot(away[..., 0], away[..., 1])
        away = away / np.where(norm > 0, norm, 1.0)[..., None]
        F = F + np.sum(mag[..., None] * away, axis=1)
    return F


def apf_lockstep(st, params: dict[str, Any] | None = None, *,
                 record_paths: bool = False) -> LockstepResult:
    """The ``apf`` planner (its parameters ``params``, defaults for the others) on every world of
    ``st`` (:func:`hybridnav.tuner.evaluate.scenario_set`: one robot each, one model) in one
    lockstep batch: run by run what :meth:`APF.run` does (the force of :func:`apf_force`, a
    local minimum ``stuck``), as arrays ``(worlds, 1)``."""
    v = APF(**(params or {})).values
    radius = st.radius
    xi, sigma0, eta, rho0 = v["xi"], v["sigma0"], v["eta"], v["rho0"]
    overrides = {"controller": "heading", "speed": v["speed"], "max_turn": v["max_turn"]}
    from hybridnav.native.lockstep import apf_run
    from hybridnav.planners.field.lockstep import prepare

    res = apf_run(prepare(st.scenarios, 1, overrides, st.stack), v, radius=radius,
                  record_paths=record_paths)
    if res is not None:                  # the compiled control cycle
        return res

    def field(env, members, P, goals, t):
        D = P - goals
        dist = np.hypot(D[:, 0], D[:, 1])
        scale = np.where(dist <= sigma0, xi, xi * sigma0 / np.where(dist > 0, dist, 1.0))
        F = -scale[:, None] * D
        if st.stack.K:
            clear, near = st.stack.nearest_each(P, env, t)
            rho = np.maximum(clear - radius[env][:, None], 1e-9)
            on = rho <= rho0                      # padding columns (inf) are never on
            mag = np.where(on, eta * (1.0 / rho - 1.0 / rho0) / rho**2, 0.0)
            away = P[:, None, :] - near
            norm = np.hypot(away[..., 0], away[..., 1])
            with np.errstate(invalid="ignore"):
                away = away / np.where(norm > 0, norm, 1.0)[..., None]
            F = F + np.sum(np.where(on[..., None], mag[..., None] * away, 0.0), axis=1)
        small = np.hypot(F[:, 0], F[:, 1]) <= v["force_tol"] * xi * sigma0
        F[small] = np.nan                         # a local minimum: stuck, as APF.velocity says
        return F

    return lockstep_field(st.scenarios, 1, field, model_overrides=overrides,
                          speed=v["speed"], stuck_window=v["stuck_window"],
                          stuck_radius=v["stuck_radius"], record_paths=record_paths,
                          stack=st.stack,
                          safety={"margin": v["safety_margin"], "max_turn": v["max_turn"]})


class APF(FieldPlanner):
    """Classical artificial potential field; stalls (outcome ``stuck``) in local minima."""

    name = "apf"
    description = "artificial potential field: quadratic/conic attraction, repulsion within rho0"
    parameters: ClassVar[dict[str, Param]] = {
        "xi": Param(1.0, "attractive gain", lo=0.0),
        "sigma0": Param(1.0, "distance at which the attraction turns from quadratic to conic",
                        lo=0.0, lo_open=True),
        "eta": Param(0.05, "repulsive gain", lo=0.0),
        "rho0": Param(0.5, "obstacle influence distance", lo=0.0, lo_open=True),
        "force_tol": Param(1e-6, "a resultant force below this (relative to xi * sigma0) is a "
                                 "local minimum", lo=0.0),
        **COMMON,
        **SENSOR,
    }
    # F_att ~ xi sigma0 (a length), F_rep ~ eta / rho^3: eta scales as length^4 so that the
    # field's directions are the same at any scale
    scaled: ClassVar[dict[str, int]] = {**FieldPlanner.scaled, "sigma0": 1, "rho0": 1, "eta": 4}
    #: |F|: the attraction xi * distance (xi a pure number) plus the repulsion, a length
    signal_units: ClassVar[dict[str, str]] = {"force": "length"}

    def gains(self, state: Any, idx: np.ndarray) -> dict[str, Any]:
        """The APF gains of the robots ``idx`` (PBPF tunes them per robot)."""
        v = self.values
        return {k: v[k] for k in ("xi", "sigma0", "eta", "rho0")}

    def velocity(self, state, sim: Simulation, idx, P, goals):
        radius = np.array([sim.models[i].radius for i in idx])
        g = self.gains(state, idx)
        F = apf_force(perceive(sim, idx, P), P, goals, radius, sim.t, **g)
        scale = self.values["force_tol"] * np.asarray(g["xi"]) * np.asarray(g["sigma0"])
        self.trace(sim, idx, force=np.hypot(F[:, 0], F[:, 1]))
        small = np.hypot(F[:, 0], F[:, 1]) <= scale
        for j in np.flatnonzero(small):
            sim.stop(int(idx[j]), "stuck")
        return F
