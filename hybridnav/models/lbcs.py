"""The Lyapunov-based control scheme (LbCS) for a point mass among circular obstacles.

Sharma & Vanualailai's construction, as compared against in the ACO-Kinematic paper: with the
target ``p = (x1, y1)``, circular obstacles ``o_l`` of radius ``r_l`` and the robot radius ``rp``::

    L(x)    = 1/2 ||x - p||^2 (1 + sum_l beta / FO_l(x))
    FO_l(x) = 1/2 (||x - o_l||^2 - (r_l + rp)^2)          (> 0 on the free space)
    xdot    = -(1/delta1) dL/dx,   ydot = -(1/delta2) dL/dy

so that along solutions ``Ldot = -(1/delta1) (dL/dx)^2 - (1/delta2) (dL/dy)^2 <= 0`` on the free
space, with equality exactly at the stationary points of ``L``: the target and the local minima
and saddles the obstacles create (where the scheme stalls). ``hybridnav.analysis`` proves the
inequality from this structure and locates the other stationary points.

Defaults follow the ACO-Kinematic paper's Table 4 for the point mass (beta = 2, delta1 = delta2 =
10). Workspace-boundary terms are not included.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import casadi as cs

from hybridnav.errors import HybridnavError
from hybridnav.models.base import Model
from hybridnav.params import Param

__all__ = ["LbCS"]


class LbCS(Model):
    """Point mass under the LbCS velocity law among circular obstacles.

    Parameters
    ----------
    dt : float
        Control and integration step (s).
    jit : bool or None
        JIT-compile the batched functions (None: when a compiler works).
    radius : float, optional
        The robot radius; the same as ``rp`` (default 0.5).
    **params
        ``obstacles`` and the numeric parameters below.
    obstacles : sequence of (cx, cy, r)
        The circular obstacles (option; part of the model's structure).
    beta, delta1, delta2, rp : float
        Obstacle gain, the two control gains and the robot radius.
    """

    name = "lbcs"
    description = "point mass under the Lyapunov-based control scheme among circles"
    analysis_scenario = "aco-local-minimum"
    plant_state_names = ("x", "y")
    #: a control scheme analysed on a scenario's circles, not a robot model scenarios name
    capabilities = frozenset()
    smooth_at_target = True
    candidate_name = "L"
    candidate_unit = None          # L multiplies and divides distances: no one unit
    input_names = ("vx", "vy")
    parameters = {
        "beta": Param(2.0, "obstacle avoidance gain beta_l (the same for every obstacle)", lo=0.0, lo_open=True),
        "delta1": Param(10.0, "control gain along x: xdot = -(1/delta1) dL/dx", lo=0.0, lo_open=True),
        "delta2": Param(10.0, "control gain along y: ydot = -(1/delta2) dL/dy", lo=0.0, lo_open=True),
        "rp": Param(0.5, "robot radius added to each obstacle radius in FO_l", lo=0.0),
        "obstacles": Param((), "circles (x, y, r) the scheme avoids", kind=tuple),
    }

    def __init__(self, dt: float = 0.1, jit: bool | None = None, radius: float | None = None,
                 **params: Any) -> None:
        obstacles = _obstacle_tuple(params.pop("obstacles", ()))
        if radius is not None and "rp" in params and params["rp"] != radius:
            raise HybridnavError(f"model lbcs: radius: the same as rp, but radius = {radius!r} and "
                                 f"rp = {params['rp']!r}; give one")
        if radius is not None and "rp" not in params:
            params["rp"] = radius
        super().__init__(dt, jit, self.defaults["rp"] if radius is None else radius,
                         obstacles=obstacles, **params)
        self._radius = self.values["rp"]

    def _validate_params(self) -> None:
        # (also after a change in place: the obstacles checked as the constructor checks them,
        # and the footprint radius is rp)
        self.options["obstacles"] = _obstacle_tuple(self.options["obstacles"])
        self._radius = self.values["rp"]

    def with_params(self, **overrides: Any) -> LbCS:
        """A copy with some parameters changed (``radius`` follows a changed ``rp``)."""
        overrides.setdefault("radius", overrides.get("rp", self.values["rp"]))
        return super().with_params(**overrides)

    @classmethod
    def from_scenario(cls, scenario, robot: str | None = None, **params: Any) -> LbCS:
        """The LbCS model for a robot of a scenario (its static circles; radius ``rp``).

        Raises
        ------
        HybridnavError
            When the scenario has obstacles other than circles (the scheme is defined for circles).
        """
        r = scenario.robots[0] if robot is None else scenario.robot(robot)
        circles = []
        for i, ob in enumerate(scenario.world.obstacles):
            if getattr(ob, "kind", None) != "circle":   # models do not import the world
                raise HybridnavError(
                    f"{scenario.source or scenario.name}: obstacles[{i}]: the LbCS model takes "
                    f"circle obstacles only, got {type(ob).__name__}"
                )
            circles.append((float(ob.center[0]), float(ob.center[1]), float(ob.radius)))
        params.setdefault("rp", r.radius)
        return cls(dt=scenario.dt, obstacles=circles, **params)

    # ---- the Lyapunov function ---------------------------------------------------------------

    def obstacle_functions(self, x, p) -> list:
        """The ``FO_l(x)`` expressions, one per obstacle."""
        q = self.p_dict(p)
        return [0.5 * ((x[0] - ox) ** 2 + (x[1] - oy) ** 2 - (r + q["rp"]) ** 2)
                for ox, oy, r in self.options["obstacles"]]

    def lyapunov_function(self, x=None, target=None, p=None) -> cs.SX:
        """``L(x) = 1/2 ||x - p||^2 (1 + sum_l beta / FO_l(x))`` (defaults: the model's symbols)."""
        s = self.sym
        x = s.x if x is None else x
        target = s.target if target is None else target
        p = s.p if p is None else p
        q = self.p_dict(p)
        attract = 0.5 * ((x[0] - target[0]) ** 2 + (x[1] - target[1]) ** 2)
        repel = 1
        for fo in self.obstacle_functions(x, p):
            repel = repel + q["beta"] / fo
        return attract * repel

    def lyapunov_candidate(self, x=None, target=None) -> cs.SX:
        """The scheme's own Lyapunov function ``L`` (see :meth:`lyapunov_function`)."""
        return self.lyapunov_function(x, target)

    def gradient_flow_gains(self, p=None) -> cs.SX:
        """The positive gains ``c_i`` of ``xdot_i = -c_i dL/dx_i`` (here ``1/delta_i``)."""
        q = self.p_dict(self.sym.p if p is None else p)
        return cs.vertcat(1 / q["delta1"], 1 / q["delta2"])

    def open_loop(self, x, u, p):
        return cs.vertcat(u[0], u[1])

    def lyapunov_gradient(self, x=None, target=None, p=None) -> cs.SX:
        """``dL/d(x, y)``, differentiated once on the model's own symbols and then substituted."""
        s = self.sym
        if not hasattr(self, "_grad_fn"):
            grad = cs.gradient(self.lyapunov_function(), s.x)
            self._grad_fn = cs.Function("lbcs_grad", [s.x, s.target, s.p], [grad])
        return self._grad_fn(s.x if x is None else x[:2], s.target if target is None else target,
                             s.p if p is None else p)

    def controller(self, x, target, p):
        return -self.gradient_flow_gains(p) * self.lyapunov_gradient(x, target, p)

    def state_constraints(self, x=None, p=None) -> cs.SX:
        """``FO_l(x) > 0`` for every obstacle: the free space."""
        x = self.sym.x if x is None else x
        p = self.sym.p if p is None else p
        fos = self.obstacle_functions(x, p)
        return cs.vertcat(*fos) if fos else cs.SX(0, 1)


def _obstacle_tuple(obstacles: Iterable[Sequence[float]]) -> tuple[tuple[float, float, float], ...]:
    if isinstance(obstacles, (str, bytes)) or not isinstance(obstacles, Iterable):
        raise HybridnavError(f"model lbcs: obstacles: expected a sequence of (cx, cy, r), got "
                             f"{obstacles!r}")
    out = []
    for i, ob in enumerate(obstacles):
        try:
            cx, cy, r = (float(v) for v in ob)
        except (TypeError, ValueError):
            raise HybridnavError(
                f"model lbcs: obstacles[{i}]: expected (cx, cy, r), got {ob!r}"
            ) from None
        if not all(math.isfinite(v) for v in (cx, cy, r)) or r <= 0:
            raise HybridnavError(
                f"model lbcs: obstacles[{i}]: expected finite numbers with r > 0, got {ob!r}"
            )
        out.append((cx, cy, r))
    return tuple(out)
