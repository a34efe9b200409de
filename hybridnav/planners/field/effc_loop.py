"""EFFC closed around a robot model, as CasADi expressions the analysis tools take.

:func:`effc_closed_loop` writes the EFFC planner's velocity field — unit attraction to the goal,
unit repulsion from the nearest point of one circular obstacle, blended by the fuzzy weight
``w = FIS(dtheta, alpha)`` (:meth:`hybridnav.fuzzy.FuzzySystem.to_casadi`, exact) — and closes the
robot model's controller around it with the target the planner passes for that velocity
(:meth:`~hybridnav.models.Model.carrot`: ``position + F_w`` for the unicycle's heading
controller). The result
is a :class:`~hybridnav.analysis.System` of the model's states: simulate it, linearize it, check
candidates on it.

What it is and is not: the continuous-time idealization of the planner's loop (the heading
controller's input is held over each control cycle in the planner; here it is the flow with the
input computed from the same state, as :meth:`~hybridnav.models.Model.closed_loop` defines for
zero-order-hold models). Its velocity field equals the planner's (:func:`effc_inputs_from`,
:func:`effc_force` and ``evaluate``) to rounding outside the obstacle.
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as cs
import numpy as np

from hybridnav.errors import HybridnavError

__all__ = ["effc_closed_loop", "effc_field"]


def effc_field(fis, p, goal: Sequence[float], circle: Sequence[float] | None,
               radius: float = 0.0):
    """EFFC's blended unit force at the position ``p`` (a CasADi 2-vector) as expressions.

    Parameters
    ----------
    fis : FuzzySystem
        With inputs ``dtheta`` and ``alpha``.
    p : casadi.SX
        The position.
    goal : (2,) sequence
    circle : (cx, cy, r) or None
        The one obstacle (None: no obstacle, the force is the attraction).
    radius : float
        The robot's footprint radius (``alpha`` uses the clearance minus it).

    Returns
    -------
    force : casadi.SX
        ``w F_rep + (1 - w) F_att`` (2-vector).
    parts : dict
        ``dtheta``, ``alpha``, ``w``, ``f_att``, ``f_rep``, ``clearance`` expressions.
    """
    to_goal = cs.DM(np.asarray(goal, dtype=float)) - p
    d_goal = cs.norm_2(to_goal)
    f_att = to_goal / d_goal
    if circle is None:
        return f_att, {"f_att": f_att}
    cx, cy, r = (float(v) for v in circle)
    away = p - cs.DM([cx, cy])
    d_c = cs.norm_2(away)
    f_rep = away / d_c                              # from the nearest circle point (outside)
    clear = d_c - r
    ang = cs.atan2(to_goal[1], to_goal[0]) - cs.atan2(-f_rep[1], -f_rep[0])
    dtheta = cs.fabs(cs.atan2(cs.sin(ang), cs.cos(ang)))
    alpha = cs.fmax(clear - radius, 0.0) / d_goal
    inputs = {"dtheta": dtheta, "alpha": alpha}
    if "clearance" in fis.input_names:              # the optional input: the footprint's gap
        inputs["clearance"] = cs.fmax(clear - radius, 0.0)
    w = fis.to_casadi(**inputs)
    force = w * f_rep + (1 - w) * f_att
    return force, {"dtheta": dtheta, "alpha": alpha, "w": w, "f_att": f_att, "f_rep": f_rep,
                   "clearance": clear}


def effc_closed_loop(model, fis, goal: Sequence[float], circle: Sequence[float] | None = None,
                     *, name: str = "effc_loop"):
    """The robot ``model`` driven by EFFC towards ``goal`` around one circular obstacle.

    Parameters
    ----------
    model : Model
        A robot model that can follow a target point (e.g. ``models.get("unicycle",
        controller="heading")``, EFFC's robot).
    fis : FuzzySystem
        The blend-weight system (e.g. ``fuzzy.builtin("effc-tuned")``).
    goal : (2,) sequence
    circle : (cx, cy, r), optional
    name : str

    Returns
    -------
    System
        States: the model's; ``details`` of the field in ``system.parts`` (expressions in its
        state symbols).

    Raises
    ------
    HybridnavError
        A fuzzy system without the inputs ``dtheta`` and ``alpha`` (``clearance`` may be a
        third).
    """
    from hybridnav.analysis.system import System

    from hybridnav.planners.base import accepts_inputs
    from hybridnav.planners.field.effc import EFFC

    if not accepts_inputs(EFFC, fis.input_names):
        raise HybridnavError(f"fis: expected a fuzzy system with the inputs dtheta and alpha "
                             f"(and optionally clearance), got {', '.join(fis.input_names)}")
    s = model.sym
    x = s.x
    force, parts = effc_field(fis, x[:2], goal, circle, radius=model.radius)
    # the planner's target for a velocity is model.carrot (affine in the velocity for the
    # built-in models: x + G v); G from two unit velocities at the origin state
    origin = np.zeros((1, model.nx))
    G = np.column_stack([model.carrot(origin, np.array([e]))[0] for e in np.eye(2)])
    target = x[:2] + cs.mtimes(cs.DM(G), force)
    rhs = cs.substitute(model.closed_loop(x, target, s.p), s.p, cs.DM(model.p_value()))
    system = System(x, None, rhs, states=model.state_names, angles=model.angle_state_names,
                    dt=model.dt, name=name, jit=model.jit)
    sx = system.sym.x
    system.parts = {k: cs.substitute(v, x, sx) for k, v in parts.items()}
    return system
