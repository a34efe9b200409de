"""Non-standard tractor-trailer robot (FAStep-Kinematic eq. 13, ACO-Kinematic eq. 15).

A rear-wheel-drive car-like tractor with an off-axle hitched two-wheel passive trailer. States
``x, y`` (the tractor's centre, half-way between its axles), ``theta0`` (tractor heading),
``theta1`` (trailer heading) and the controller state ``xi``; inputs ``v`` (rear-axle speed) and
``phi`` (steering angle)::

    xdot      = v cos th0 - (v/2) tan(phi) sin th0
    ydot      = v sin th0 + (v/2) tan(phi) cos th0
    th0dot    = (v/L) tan(phi)
    th1dot    = (v/Lt) (sin(th0 - th1) - (c/L) tan(phi) cos(th0 - th1))

(the ``v/2`` terms say that ``(x, y)`` lies ``L/2`` ahead of the rear axle; ``c`` is the hitch's
distance behind the rear axle and ``Lt`` the hitch-to-trailer-axle length). The go-to-point law::

    v    = alpha * distance to the target
    phi  = (7/9) atan(xi + beta / cos|th0 - th1|)
    beta = max{0, 0.5 - cos|th1 - th0|} * sign(th1 - th0)

``xi`` law (option ``xi_law``):

``"filter"`` (default)
    ``xidot = k_xi (wrap(atan2(y1 - y, x1 - x) - th0) - xi)``: ``xi`` follows the heading error to
    the target with time constant ``1 / k_xi``. :meth:`retarget` sets
    ``xi = wrap(atan2(y1 - y, x1 - x) - th0)`` whenever a robot gets a new target.
``"paper"``
    The law as the papers print it, ``xidot = ((y1 - y) cos th0 - (x1 - x) sin th0) /
    sqrt((x - x1)^2 + (y - y1)^2 + 0.01) - atan2(y1 - y, x1 - x) + th0``. Simulated as printed,
    ``xi`` hardly moves, the steering angle stays nearly constant and the robot circles: the first
    term is the sine of the heading error and the rest is minus the (unwrapped) heading error, so
    ``xidot ~ sin(e) - e``, which is tiny for small errors. Kept so that anyone can see it.

Limits of the law (both ``xi`` laws): the speed is proportional to the distance and the steering
is bounded, so near the target the heading error ``e`` obeys roughly
``edot = alpha e (1 - 7 d / (9 L))``: it decays while ``d > 9L/7`` and grows inside. A robot that
has not lined up with its target by then settles on an orbit about ``L/2`` to ``1.5 L`` from it
instead of reaching it (tested). Robots that start far enough away (about ``10 L``, for
initial heading errors up to 90 degrees) line up in time and reach it; planners should keep
waypoints farther apart than ``9L/7`` or use a goal radius larger than the orbit.

The footprint is the tractor body (``L`` x ``b``, centred on ``(x, y)``) and the trailer body
(``Lt`` x ``b``, from the hitch to the trailer axle), each covered by a row of disks.
"""

from __future__ import annotations

import math

import casadi as cs
import numpy as np

from hybridnav.models.base import Model, wrap_angle
from hybridnav.params import Param

__all__ = ["TractorTrailer"]


class TractorTrailer(Model):
    """Tractor with an off-axle hitched trailer and the papers' steering law."""

    name = "tractor_trailer"
    description = "car-like tractor with an off-axle hitched passive trailer (states x, y, th0, th1, xi)"
    analysis_scenario = "tractor-trailer-1"
    #: "trailer": a body of several covering disks, not one disk
    capabilities = frozenset({"robot", "trailer"})
    footprint_from_params = True      # the covering disks follow from L and b
    analysis_slice = {"theta0": 0.0, "theta1": 0.0, "xi": 0.0}
    straight_driving = (1.0, 0.0)      # v = 1, phi = 0
    plant_state_names = ("x", "y", "theta0", "theta1")
    controller_state_names = ("xi",)
    #: headings, and xi the steering state (an angle: it follows the heading error)
    state_units = {"x": "length", "y": "length", "theta0": "rad", "theta1": "rad", "xi": "rad"}
    input_names = ("v", "phi")
    parameters = {
        "L": Param(1.6, "tractor length between axles (the tractor body is L long)", lo=0.0, lo_open=True),
        "Lt": Param(1.2, "trailer length, hitch to trailer axle", lo=0.0, lo_open=True),
        "c": Param(0.5, "hitch offset behind the tractor's rear axle", lo=0.0),
        "b": Param(1.0, "body width of tractor and trailer", lo=0.0, lo_open=True),
        "alpha": Param(0.1, "speed gain, v = alpha * distance to the target (1/s)", lo=0.0, lo_open=True),
        "k_xi": Param(2.0, "xi_law='filter': rate at which xi follows the heading error (1/s)",
                      lo=0.0, lo_open=True),
        "xi_law": Param("filter", "filter (smooth xi) or paper (the papers' law)",
                        choices=("filter", "paper")),
    }

    def open_loop(self, x, u, p):
        q = self.p_dict(p)
        th0, th1 = x[2], x[3]
        v, tphi = u[0], cs.tan(u[1])
        return cs.vertcat(
            v * cs.cos(th0) - v / 2 * tphi * cs.sin(th0),
            v * cs.sin(th0) + v / 2 * tphi * cs.cos(th0),
            v / q["L"] * tphi,
            v / q["Lt"] * (cs.sin(th0 - th1) - q["c"] / q["L"] * tphi * cs.cos(th0 - th1)),
        )

    def controller(self, x, target, p):
        q = self.p_dict(p)
        dx, dy = target[0] - x[0], target[1] - x[1]
        th0, th1, xi = x[2], x[3], x[4]
        v = q["alpha"] * cs.sqrt(dx**2 + dy**2)
        gap = cs.fabs(th0 - th1)
        beta = cs.fmax(0, 0.5 - cs.cos(gap)) * cs.sign(th1 - th0)
        phi = 7.0 / 9.0 * cs.atan(xi + beta / cs.cos(gap))
        return cs.vertcat(v, phi)

    def controller_dynamics(self, x, target, p):
        q = self.p_dict(p)
        dx, dy = target[0] - x[0], target[1] - x[1]
        th0, xi = x[2], x[4]
        if self.options["xi_law"] == "paper":
            return (dy * cs.cos(th0) - dx * cs.sin(th0)) / cs.sqrt(dx**2 + dy**2 + 0.01) - cs.atan2(
                dy, dx
            ) + th0
        return q["k_xi"] * (wrap_angle(cs.atan2(dy, dx) - th0) - xi)

    def carrot_divisor(self) -> tuple[float, float]:
        """``x + velocity / alpha``: the speed ``alpha * distance`` is then ``|velocity|``."""
        return (float(self.values["alpha"]),) * 2

    def retarget(self, X, targets) -> np.ndarray:
        """Set ``xi = wrap(atan2(y1 - y, x1 - x) - theta0)`` for each robot's new target."""
        X, targets = self._check_batch(X, targets)
        X = X.copy()
        err = np.arctan2(targets[:, 1] - X[:, 1], targets[:, 0] - X[:, 0]) - X[:, 2]
        X[:, 4] = np.arctan2(np.sin(err), np.cos(err))
        return X

    @property
    def radius(self) -> float:
        """Half-diagonal of the tractor body, ``sqrt(L^2 + b^2) / 2`` (the papers' clearance)."""
        return math.hypot(self.values["L"], self.values["b"]) / 2

    @property
    def footprint_extent(self) -> float:
        """How far the footprint's disks reach from ``(x, y)`` at most: the tractor's disks
        are centred on its axis within ``L/2`` of it, the trailer's on its axis at most
        ``L/2 + c + Lt`` behind it (the hitch is ``L/2 + c`` behind ``(x, y)``)."""
        q = self.values
        (lt, nt, rt), (lr, nr, rr) = self._bodies()
        tractor = (nt - 0.5) / nt * lt - lt / 2 + rt
        trailer = q["L"] / 2 + q["c"] + (nr - 0.5) / nr * lr + rr
        return max(tractor, trailer)

    def _bodies(self):
        """(offset of the body centre along its axis from its anchor, length, disks) per body."""
        q = self.values
        out = []
        for length in (q["L"], q["Lt"]):
            n = max(1, math.ceil(length / q["b"]))
            out.append((length, n, math.hypot(length / (2 * n), q["b"] / 2)))
        return out

    def footprint(self, X) -> tuple[np.ndarray, np.ndarray]:
        """Disks covering the tractor body and the trailer body.

        Returns
        -------
        centers : ndarray, shape (N, m, 2)
        radii : ndarray, shape (m,)
        """
        X = np.asarray(X, dtype=float).reshape(-1, self.nx)
        s_t, s_r, back, radii = self._disk_layout()
        nt = len(s_t)
        c0, s0 = np.cos(X[:, 2]), np.sin(X[:, 2])
        c1, s1 = np.cos(X[:, 3]), np.sin(X[:, 3])
        px, py = X[:, 0], X[:, 1]
        # tractor: centred on (x, y); trailer: from the hitch back to the trailer axle (one
        # coordinate at a time: NumPy is slow on a last axis of length 2)
        hx, hy = px - back * c0, py - back * s0
        centers = np.empty((len(X), nt + len(s_r), 2))
        for i, s in enumerate(s_t):
            centers[:, i, 0] = px + s * c0
            centers[:, i, 1] = py + s * s0
        for i, s in enumerate(s_r):
            centers[:, nt + i, 0] = hx - s * c1
            centers[:, nt + i, 1] = hy - s * s1
        return centers, radii.copy()

    def outline(self, X) -> list[np.ndarray]:
        """The tractor body (``L`` x ``b`` centred on ``(x, y)`` along ``theta0``) and the trailer
        body (``Lt`` x ``b`` from the hitch back along ``theta1``) as rectangles.

        Parameters
        ----------
        X : array_like, shape (N, nx)
            States.

        Returns
        -------
        list of ndarray, shape (N, 4, 2)
            Tractor, trailer: their corners counter-clockwise.
        """
        X = np.asarray(X, dtype=float).reshape(-1, self.nx)
        q = self.values
        half = q["b"] / 2
        px, py = X[:, 0], X[:, 1]
        back = q["L"] / 2 + q["c"]
        hx, hy = px - back * np.cos(X[:, 2]), py - back * np.sin(X[:, 2])

        def box(cx, cy, th, s0, s1):
            # corners at offsets s0 (rear) .. s1 (front) along the heading, +-half across it
            u = np.stack([np.cos(th), np.sin(th)], axis=-1)
            n = np.stack([-u[:, 1], u[:, 0]], axis=-1)
            c = np.stack([cx, cy], axis=-1)
            return np.stack([c + s0 * u - half * n, c + s1 * u - half * n,
                             c + s1 * u + half * n, c + s0 * u + half * n], axis=1)

        return [box(px, py, X[:, 2], -q["L"] / 2, q["L"] / 2),
                box(hx, hy, X[:, 3], -q["Lt"], 0.0)]

    def _disk_layout(self) -> tuple[list[float], list[float], float, np.ndarray]:
        """The footprint's disks, which depend on the parameters only: offsets of the tractor's
        disk centres along its axis from ``(x, y)`` and of the trailer's from the hitch, the
        hitch's distance behind ``(x, y)``, the radii (kept until a parameter changes: the sweep
        asks for footprints hundreds of times a step)."""
        q = self.values
        key = (q["L"], q["Lt"], q["b"], q["c"])
        got = self.__dict__.get("_disk_layout_cache")
        if got is None or got[0] != key:
            (lt, nt, rt), (lr, nr, rr) = self._bodies()
            s_t = ((np.arange(nt) + 0.5) / nt * lt - lt / 2).tolist()
            s_r = ((np.arange(nr) + 0.5) / nr * lr).tolist()
            radii = np.concatenate([np.full(nt, rt), np.full(nr, rr)])
            got = (key, (s_t, s_r, q["L"] / 2 + q["c"], radii))
            self.__dict__["_disk_layout_cache"] = got
        return got[1]
