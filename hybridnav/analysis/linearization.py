"""Exact linearization of the CasADi models into python-control state-space systems."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import casadi as cs
import control
import numpy as np

from hybridnav.errors import HybridnavError
from hybridnav.models.base import Model

__all__ = ["DiscreteStepReport", "LinearizationReport", "controllability_rank", "discrete_step",
           "is_stable", "linearize", "linearize_expression", "rk4_stability_limit", "summarize"]


def linearize(
    model: Model,
    x0: Sequence[float],
    u0: Sequence[float] | None = None,
    *,
    target: Sequence[float] | None = None,
    name: str | None = None,
) -> control.StateSpace:
    """Linearize a model with CasADi's exact Jacobians.

    Two modes:

    * **open loop** (``target`` is None): ``dx/dt = f(x, u)`` about ``(x0, u0)`` over the plant
      states; ``A = df/dx``, ``B = df/du``. The point need not be an equilibrium (e.g. straight
      driving): ``f(x0, u0)`` is then the nominal velocity and the system describes deviations.
    * **closed loop** (``target`` given): ``dx/dt = F(x, target)`` about ``x0``, with the target as
      input; ``A = dF/dx``, ``B = dF/d(x1, y1)``.

    ``C`` is the identity (every state is an output) and ``D = 0``. The result is a
    ``control.StateSpace`` with named states, inputs and outputs; ``sys.nominal_rate`` holds
    ``f(x0, u0)`` (resp. ``F(x0)``).

    Parameters
    ----------
    model : Model or any system
        A hybridnav model, or a python-control ``nlsys`` / ``StateSpace``, a CasADi
        ``Function``, ``(x, u, rhs)`` expressions or a do-mpc model
        (:func:`hybridnav.analysis.as_system`): ``linearize(sys, x0, u0)`` returns its
        ``ct.StateSpace`` about ``(x0, u0)`` as ``control.linearize`` would, with exact Jacobians.
    x0 : sequence of float
        The point: plant states (open loop) or all states (closed loop).
    u0 : sequence of float, optional
        The input of the open-loop point (required for a robot's open loop; a system's held
        input by default).
    target : (float, float), optional
        Linearize the closed loop driving to it (default: the open loop).
    name : str, optional
        The system's name (default ``"<model>_lin"``).

    Raises
    ------
    HybridnavError
        Wrong sizes, or a Jacobian entry that is not finite (the model is not differentiable
        there, e.g. the unicycle's heading controller at its target): the message names the state
        rows.
    """
    from hybridnav.analysis.system import as_system

    model = as_system(model)
    x0 = _vector(x0, "x0")
    s = model.sym
    pval = cs.DM(model.p_value())
    if target is None and u0 is None and hasattr(model, "u0"):
        u0 = model.u0                      # a system: its held input
    if target is None:
        if u0 is None:
            raise HybridnavError(
                f"u0: expected the nominal input ({', '.join(model.input_names)}) for an open-loop"
                " linearization (or pass target= for the closed loop)"
            )
        u0 = _vector(u0, "u0")
        if x0.size != model.n_plant or u0.size != model.nu:
            raise HybridnavError(
                f"x0, u0: expected {model.n_plant} plant states ({', '.join(model.plant_state_names)})"
                f" and {model.nu} inputs ({', '.join(model.input_names)}), got {x0.size} and "
                f"{u0.size}"
            )
        xs = s.x[: model.n_plant]
        f = cs.substitute(model.open_loop(xs, s.u, s.p), s.p, pval)
        fn = cs.Function("lin", [xs, s.u], [f, cs.jacobian(f, xs), cs.jacobian(f, s.u)])
        rate, A, B = (np.asarray(a, dtype=float) for a in fn(x0, u0))
        A, B = A.reshape(model.n_plant, model.n_plant), B.reshape(model.n_plant, model.nu)
        states, inputs = list(model.plant_state_names), list(model.input_names)
        point, args = (x0, u0), cs.Function("f", [xs, s.u], [f])
        expr = ([xs, s.u], f)
    else:
        t = _vector(target, "target")
        if x0.size != model.nx or t.size != model.target_size:
            raise HybridnavError(
                f"x0: expected {model.nx} states ({', '.join(model.state_names)}) and a "
                f"{model.target_size}-vector target, got {x0.size} and {t.size}"
            )
        f = cs.substitute(model.closed_loop(), s.p, pval)
        fn = cs.Function("lin", [s.x, s.target],
                         [f, cs.jacobian(f, s.x), cs.jacobian(f, s.target)])
        rate, A, B = (np.asarray(a, dtype=float) for a in fn(x0, t))
        states, inputs = list(model.state_names), [str(v) for v in cs.vertsplit(s.target)]
        point, args = (x0, t), cs.Function("f", [s.x, s.target], [f])
        expr = ([s.x, s.target], f)
    bad = sorted({states[i] for i in np.argwhere(~np.isfinite(np.hstack([A, B])))[:, 0]})
    if bad:
        raise HybridnavError(
            f"x0: {model.name} is not differentiable at {x0.tolist()}: the Jacobian rows of "
            f"{', '.join(bad)} are not finite there"
        )
    _one_sided(model.name, args, point, [states, inputs], x0, expr=expr)
    sys = _ss(A, B, states, inputs, name or f"{model.name}_lin")
    sys.nominal_rate = rate.ravel()
    return sys


def _ss(A, B, states, inputs, name) -> control.StateSpace:
    """``control.ss(A, B, I, 0)`` with named signals; also for one state and no input, which
    python-control 0.10 refuses to build (it reads a (1, 0) matrix as (0, 0))."""
    n, m = A.shape[0], B.shape[1]
    if n == 1 and m == 0:
        sys = control.ss(A, np.zeros((1, 1)), np.eye(1), np.zeros((1, 1)), states=list(states),
                         outputs=list(states), name=name)
        sys.B, sys.D = np.zeros((1, 0)), np.zeros((1, 0))
        sys.ninputs, sys.input_index = 0, {}
        return sys
    return control.ss(A, B, np.eye(n), np.zeros((n, m)), states=list(states),
                      inputs=list(inputs), outputs=list(states), name=name)


def _one_sided(what: str, f: cs.Function, point, names, x0, rtol: float = 1e-3,
               expr=None) -> None:
    """Raise where ``f`` has a kink (``fmax``, ``fabs``) or a jump (an angle wrapping at pi) at the
    point, which CasADi's Jacobian, a one-sided derivative itself, does not show.

    Where the expression ``expr = (symbols, f)`` has an interval extension, only the rows that
    pass through an operation at or within ``1e-8`` (relative) of its kink or jump are examined
    (:class:`~hybridnav.analysis.interval.IntervalFunction`'s smoothness flags), so curvature at
    large coordinates (``sin`` at ``1e6``) is never taken for a kink; those rows are then
    confirmed by one-sided difference quotients with the same step.
    """
    point = [np.asarray(p, dtype=float).ravel() for p in point]
    rows = None
    if expr is not None:
        from hybridnav.analysis.interval import IntervalFunction, UnsupportedOperation

        syms, fx = expr
        try:
            F = IntervalFunction(cs.vertcat(*syms), [fx])
        except UnsupportedOperation:
            F = None
        if F is not None:
            pt = np.concatenate(point)
            h = 1e-8 * (1.0 + np.abs(pt))
            _, _, smooth = F((pt - h)[None], (pt + h)[None])
            rows = np.flatnonzero(~smooth[0])
            if not len(rows):
                return
    f0 = np.asarray(f(*point), dtype=float).ravel()
    for a, (p, labels) in enumerate(zip(point, names)):
        for j in range(p.size):
            h = (1e-8 if rows is not None else 1e-6) * (1.0 + abs(p[j]))
            quot = []
            for sign in (1.0, -1.0):
                q = [v.copy() for v in point]
                q[a][j] += sign * h
                quot.append(sign * (np.asarray(f(*q), dtype=float).ravel() - f0) / h)
            dp, dm = quot
            gap = np.abs(dp - dm)
            if rows is not None:
                # rows that pass through a kink here: any slope change beyond rounding counts,
                # relative to the slopes themselves (a jump from 5e-5 to -1.5e-4 is a kink)
                bad = gap > rtol * (np.abs(dp) + np.abs(dm)) + 1e-300
                bad &= np.isin(np.arange(len(bad)), rows)
            else:
                bad = gap > rtol * (1.0 + np.abs(dp) + np.abs(dm))
            if np.any(bad):
                i = int(np.argmax(np.where(bad, gap, -np.inf)))
                raise HybridnavError(
                    f"x0: {what} is not differentiable at {np.asarray(x0).tolist()}: along "
                    f"{labels[j]}, the one-sided derivatives of row {i} are {dp[i]:.6g} and "
                    f"{dm[i]:.6g} (a kink or a jump there)")


def linearize_expression(
    z: cs.SX, zdot: cs.SX, z0: Sequence[float], names: Sequence[str], *,
    symbols: cs.SX | None = None, values: Sequence[float] | None = None, name: str = "lin",
) -> control.StateSpace:
    """Linearize an autonomous CasADi vector field ``zdot(z)`` about ``z0`` (exact Jacobian).

    ``symbols`` / ``values`` substitute parameters first (e.g. ``model.sym.p`` and
    ``model.p_value()``). The result has no inputs (``B`` is ``(n, 0)``) and ``C = I``.

    Parameters
    ----------
    z : casadi.SX
        The state symbols.
    zdot : casadi.SX
        Their derivatives.
    z0 : sequence of float
        The point.
    names : sequence of str
        State names.
    symbols, values : optional
        Parameter symbols and their values, substituted first.
    name : str
        The system's name.
    """
    if symbols is not None:
        zdot = cs.substitute(zdot, symbols, cs.DM(np.asarray(values, dtype=float)))
    fn = cs.Function("lin", [z], [zdot, cs.jacobian(zdot, z)])
    rate, A = (np.asarray(a, dtype=float) for a in fn(_vector(z0, "z0")))
    if not np.all(np.isfinite(A)):
        raise HybridnavError(f"z0: the vector field is not differentiable at {list(z0)}")
    _one_sided("the vector field", cs.Function("f", [z], [zdot]), (_vector(z0, "z0"),),
               [list(names)], list(z0), expr=([z], zdot))
    sys = _ss(A, np.zeros((A.shape[0], 0)), names, [], name)
    sys.nominal_rate = rate.ravel()
    return sys


def is_stable(sys: control.StateSpace, tol: float = 1e-12) -> bool:
    """Whether every eigenvalue of ``A`` has a real part below ``-tol`` (asymptotic stability).

    Parameters
    ----------
    sys : control.StateSpace
    tol : float
        Margin below zero the real parts must keep.
    """
    return bool(np.all(np.linalg.eigvals(sys.A).real < -tol))


def controllability_rank(sys: control.StateSpace) -> int:
    """Rank of the controllability matrix ``control.ctrb(A, B)``."""
    if sys.ninputs == 0:
        return 0
    return int(np.linalg.matrix_rank(control.ctrb(sys.A, sys.B)))


@dataclass
class LinearizationReport:
    """Eigenvalues, stability and controllability of a linearization."""

    name: str
    point: dict[str, float]
    A: np.ndarray
    B: np.ndarray
    eigenvalues: np.ndarray
    stable: bool
    controllability_rank: int | None
    n_states: int
    nominal_rate: np.ndarray

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary."""
        return {
            "name": self.name, "point": self.point, "A": self.A.tolist(), "B": self.B.tolist(),
            "eigenvalues": [[float(e.real), float(e.imag)] for e in self.eigenvalues],
            "stable": self.stable, "controllability_rank": self.controllability_rank,
            "n_states": self.n_states, "n_inputs": int(self.B.shape[1]) if self.B.ndim == 2 else 0,
            "controllable": (self.controllability_rank == self.n_states
                             if self.controllability_rank is not None else None),
            "nominal_rate": self.nominal_rate.tolist(),
        }


def summarize(sys: control.StateSpace, point: dict[str, float] | None = None) -> LinearizationReport:
    """Eigenvalues, stability and controllability rank of a linearized system.

    Parameters
    ----------
    sys : control.StateSpace
        From :func:`linearize`.
    point : dict, optional
        State name -> value of the linearization point (for the report).
    """
    return LinearizationReport(
        name=sys.name, point=dict(point or {}), A=np.asarray(sys.A), B=np.asarray(sys.B),
        eigenvalues=np.linalg.eigvals(sys.A), stable=is_stable(sys),
        # no inputs: controllability does not apply (a rank of 0 would read "uncontrollable")
        controllability_rank=controllability_rank(sys) if sys.ninputs else None,
        n_states=sys.nstates,
        nominal_rate=np.asarray(getattr(sys, "nominal_rate", np.zeros(sys.nstates))),
    )


def _vector(v, key: str) -> np.ndarray:
    try:
        a = np.asarray(v, dtype=float).ravel()
    except (TypeError, ValueError):
        raise HybridnavError(f"{key}: expected a vector of numbers, got {v!r}") from None
    if not np.all(np.isfinite(a)):
        raise HybridnavError(f"{key}: expected finite numbers, got {a.tolist()}")
    return a


def rk4_stability_limit() -> float:
    """The length of RK4's real stability interval: ``|R(-z)| < 1`` for ``0 < z < z*``, where
    ``R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24`` is its amplification factor on ``xdot = lambda x``
    (``z = -lambda dt``). Computed as the positive real root of ``R(-z) = 1``, i.e. of
    ``z^3/24 - z^2/6 + z/2 - 1`` (``R(-z)`` stays above -1 for all real ``z``); about 2.7853."""
    roots = np.roots([1 / 24, -1 / 6, 1 / 2, -1.0])
    real = roots[np.abs(roots.imag) < 1e-9].real
    return float(np.min(real[real > 0]))


@dataclass
class DiscreteStepReport:
    """Stability of the simulated system: one control cycle (RK4, with the model's input hold) as
    a map ``x_{k+1} = Phi(x_k)`` linearized at an equilibrium."""

    point: list[float]
    dt: float
    spectral_radius: float
    eigenvalues: np.ndarray
    stable: bool

    def to_dict(self) -> dict[str, Any]:
        return {"point": self.point, "dt": self.dt, "spectral_radius": self.spectral_radius,
                "eigenvalues": [[float(e.real), float(e.imag)] for e in self.eigenvalues],
                "stable": self.stable}


def discrete_step(model: Model, x0: Sequence[float], target: Sequence[float]) -> DiscreteStepReport:
    """Linearize one simulated control cycle at ``x0`` (an equilibrium of the closed loop driving
    to ``target``): the Jacobian of the RK4 step map, exactly, from CasADi. The simulated system is
    locally stable there when its spectral radius is below 1 — for the point mass exactly when
    ``alpha_i dt`` is below :func:`rk4_stability_limit`.

    Parameters
    ----------
    model : Model
    x0 : sequence of float
        The state (an equilibrium of the closed loop).
    target : (float, float)

    Raises
    ------
    HybridnavError
        The step map is not differentiable at ``x0`` (a Jacobian entry that is not finite).
    """
    x0 = _vector(x0, "x0")
    s = model.sym
    J = cs.Function("dstep", [s.x, s.target, s.p], [cs.jacobian(model._rk4_expr(), s.x)])
    A = np.asarray(J(x0, _vector(target, "target"), model.p_value()), dtype=float)
    if not np.all(np.isfinite(A)):
        raise HybridnavError(f"model {model.name}: the step map is not differentiable at "
                             f"{x0.tolist()}")
    ev = np.linalg.eigvals(A)
    rho = float(np.max(np.abs(ev)))
    return DiscreteStepReport(point=x0.tolist(), dt=float(model.dt), spectral_radius=rho,
                              eigenvalues=ev, stable=rho < 1.0)
