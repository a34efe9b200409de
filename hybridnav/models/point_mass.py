"""Point-mass robot (FAStep-Kinematic / ACO-Kinematic papers, eq. 12 of FAStep-Kinematic).

Open loop: the robot's velocity is its input, ``xdot = u1``, ``ydot = u2``. Go-to-point controller
``u = (alpha1 (x1 - x), alpha2 (y1 - y))``, so the closed loop is
``xdot = alpha1 (x1 - x)``, ``ydot = alpha2 (y1 - y)``, with the closed form
``x(t) = x1 + (x0 - x1) exp(-alpha1 t)``.
"""

from __future__ import annotations

import casadi as cs

from hybridnav.models.base import Model
from hybridnav.params import Param

__all__ = ["PointMass"]


class PointMass(Model):
    """Holonomic point mass with the papers' proportional go-to-point controller."""

    name = "point_mass"
    description = "holonomic point mass, xdot = alpha1 (x1 - x), ydot = alpha2 (y1 - y)"
    analysis_scenario = "fastep-s1"
    capabilities = frozenset({"robot", "disk", "holonomic"})
    smooth_at_target = True
    plant_state_names = ("x", "y")
    input_names = ("vx", "vy")
    parameters = {
        "alpha1": Param(0.1, "convergence gain along x (1/s); > 0 for stability "
                        "(FAStep-Kinematic Theorem 1), required for a robot in a scenario",
                        lo=-1e6, hi=1e6),
        "alpha2": Param(0.1, "convergence gain along y (1/s); as alpha1", lo=-1e6, hi=1e6),
    }
    robot_parameters = {k: Param(0.1, "a robot's convergence gain (1/s)", lo=0.0, lo_open=True,
                                 hi=1e6) for k in ("alpha1", "alpha2")}

    def carrot_divisor(self) -> tuple[float, float]:
        """``x + (vx / alpha1, vy / alpha2)``: the controller then commands exactly ``velocity``."""
        return (float(self.values["alpha1"]), float(self.values["alpha2"]))

    def open_loop(self, x, u, p):
        return cs.vertcat(u[0], u[1])

    def controller(self, x, target, p):
        q = self.p_dict(p)
        return cs.vertcat(q["alpha1"] * (target[0] - x[0]), q["alpha2"] * (target[1] - x[1]))
