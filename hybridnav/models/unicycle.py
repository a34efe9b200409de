"""Differential-drive (unicycle) robot, e.g. a TurtleBot3 (RFD-PSO and EFFC papers).

Open loop with wheel speeds as inputs: ``v = (vl + vr) / 2``, ``omega = (vr - vl) / L``,
``xdot = v cos(theta)``, ``ydot = v sin(theta)``, ``thetadot = omega``.

Controllers (option ``controller``):

``"go_to_point"`` (default, continuous)
    With ``rho`` the distance to the target and ``e = wrap(atan2(y1 - y, x1 - x) - theta)`` the
    heading error: ``v = k_rho rho cos(e)``, ``omega = k_alpha e``. The wheel speeds
    ``vr, vl = v +- omega L / 2`` are scaled down together (keeping the curvature) when one exceeds
    ``wheel_max``. With ``k_rho, k_alpha > 0`` the distance decreases whenever ``|e| < pi/2`` and the
    heading error decays exponentially, so the robot reaches the target from any start.

``"heading"`` (zero-order hold; the EFFC paper's robot)
    Constant speed ``speed``; the commanded heading is the direction from the robot to its target
    point (the EFFC planner passes ``position + force``). Each control cycle the heading turns by
    ``clip(wrap(psi - theta), -max_turn, max_turn)`` (``max_turn = pi/4`` by default): the input
    ``omega`` is that angle divided by ``dt`` and held for the cycle.

Body-rate limits (both controllers; ``inf``, the default, is none and changes no result): the
commanded linear speed is saturated to ``|v| <= v_max`` and the turn rate to
``|omega| <= omega_max`` before they become wheel speeds, as a robot's motor driver does (a
TurtleBot3 Burger: ``v_max = 0.22`` m/s, ``omega_max = 2.84`` rad/s; the ``turtlebot-office``
scenario sets them). With ``dt = 0.1`` the heading controller's ``max_turn = pi/4`` per cycle asks
for up to 7.85 rad/s, so ``omega_max = 2.84`` binds whenever the heading error exceeds 0.284 rad.
"""

from __future__ import annotations

import math

import casadi as cs

from hybridnav.models.base import Model, wrap_angle
from hybridnav.params import Param

__all__ = ["Unicycle"]


def _clip(x, limit):
    """``x`` saturated to ``[-limit, limit]`` (exactly ``x`` for ``limit = inf``)."""
    return cs.fmin(cs.fmax(x, -limit), limit)


class Unicycle(Model):
    """Differential-drive robot with go-to-point or rate-limited heading control."""

    name = "unicycle"
    description = "differential drive (TurtleBot3-like), wheel speeds vl, vr"
    analysis_scenario = "effc-train-1"
    #: "heading_control": the "heading" controller option drives it at constant speed
    capabilities = frozenset({"robot", "disk", "heading_control"})
    analysis_slice = {"theta": 0.0}
    straight_driving = (0.1, 0.1)      # vl = vr
    plant_state_names = ("x", "y", "theta")
    angle_state_names = ("theta",)
    state_units = {"x": "length", "y": "length", "theta": "rad"}
    input_names = ("vl", "vr")
    parameters = {
        "L": Param(0.16, "distance between the driving wheels (TurtleBot3 Burger: 0.16 m)",
                   lo=0.0, lo_open=True),
        "k_rho": Param(0.5, "go_to_point: speed gain, v = k_rho * distance * cos(heading error)",
                       lo=0.0, lo_open=True),
        "k_alpha": Param(2.0, "go_to_point: turn gain, omega = k_alpha * heading error",
                         lo=0.0, lo_open=True),
        "wheel_max": Param(math.inf, "go_to_point: wheel speed limit (inf: none)",
                           lo=0.0, lo_open=True, allow_inf=True),
        "speed": Param(0.1, "heading: constant forward speed", lo=0.0, lo_open=True),
        "max_turn": Param(math.pi / 4, "heading: largest heading change per control cycle (rad)",
                          lo=0.0, lo_open=True),
        "v_max": Param(math.inf, "largest commanded linear speed |v| (inf: none; TurtleBot3 "
                   "Burger: 0.22 m/s)", lo=0.0, lo_open=True, allow_inf=True),
        "omega_max": Param(math.inf, "largest commanded turn rate |omega| (rad/s; inf: none; "
                       "TurtleBot3 Burger: 2.84)", lo=0.0, lo_open=True, allow_inf=True),
        "controller": Param("go_to_point", "go_to_point (continuous) or heading (constant speed, "
                            "held each cycle)", choices=("go_to_point", "heading")),
    }

    @property
    def hold(self) -> str:  # type: ignore[override]
        return "zoh" if self.options["controller"] == "heading" else "continuous"

    def carrot_divisor(self) -> tuple[float, float]:
        """Heading controller: ``x + velocity`` (its direction; the speed is the ``speed``
        param). Go-to-point: ``x + velocity / k_rho`` (that speed once the robot faces that
        way)."""
        if self.options["controller"] == "heading":
            return (1.0, 1.0)
        return (float(self.values["k_rho"]),) * 2

    def polar_error_dynamics(self) -> tuple[cs.SX, cs.SX, tuple[str, str]]:
        """The go-to-point closed loop in polar error coordinates ``(rho, e)``.

        With ``rho`` the distance to the target and ``e`` the heading error (no wheel saturation)::

            rhodot = -k_rho rho cos(e)^2
            edot   =  k_rho sin(e) cos(e) - k_alpha e

        Unlike the Cartesian closed loop, this is differentiable at the target ``(0, 0)``, where
        its linearization is ``diag(-k_rho, k_rho - k_alpha)``: stable when ``k_alpha > k_rho``.

        Returns
        -------
        z : casadi.SX
            The symbols ``(rho, e)``.
        zdot : casadi.SX
            Their derivatives, in the model's parameter symbols ``self.sym.p``.
        names : tuple of str
        """
        q = self.p_dict(self.sym.p)
        rho, e = cs.SX.sym("rho"), cs.SX.sym("e")
        zdot = cs.vertcat(-q["k_rho"] * rho * cs.cos(e) ** 2,
                          q["k_rho"] * cs.sin(e) * cs.cos(e) - q["k_alpha"] * e)
        return cs.vertcat(rho, e), zdot, ("rho", "e")

    def body_rates(self, u, p):
        """``v = (vl + vr) / 2``, ``omega = (vr - vl) / L``."""
        q = self.p_dict(p)
        return cs.vertcat((u[0] + u[1]) / 2, (u[1] - u[0]) / q["L"])

    def open_loop(self, x, u, p):
        q = self.p_dict(p)
        v = (u[0] + u[1]) / 2
        omega = (u[1] - u[0]) / q["L"]
        return cs.vertcat(v * cs.cos(x[2]), v * cs.sin(x[2]), omega)

    def controller(self, x, target, p):
        q = self.p_dict(p)
        dx, dy = target[0] - x[0], target[1] - x[1]
        e = wrap_angle(cs.atan2(dy, dx) - x[2])
        if self.options["controller"] == "heading":
            v = cs.fmin(q["speed"], q["v_max"])
            omega = _clip(cs.fmin(cs.fmax(e, -q["max_turn"]), q["max_turn"]) / self.dt,
                          q["omega_max"])
            return cs.vertcat(v - omega * q["L"] / 2, v + omega * q["L"] / 2)
        rho = cs.sqrt(dx**2 + dy**2)
        v = _clip(q["k_rho"] * rho * cs.cos(e), q["v_max"])
        omega = _clip(q["k_alpha"] * e, q["omega_max"])
        vl, vr = v - omega * q["L"] / 2, v + omega * q["L"] / 2
        scale = cs.fmax(1, cs.fmax(cs.fabs(vl), cs.fabs(vr)) / q["wheel_max"])
        return cs.vertcat(vl / scale, vr / scale)
