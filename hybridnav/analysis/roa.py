"""Region-of-attraction estimates from Lyapunov level sets, confirmed by batched simulation."""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import casadi as cs
import numpy as np

from hybridnav.analysis.lyapunov import (
    _candidate,
    check_lyapunov,
    find_equilibria,
    is_gradient_flow,
    lyapunov_functions,
)
from hybridnav.analysis.region import Box, as_box
from hybridnav.errors import HybridnavError
from hybridnav.models.base import Model

log = logging.getLogger(__name__)

__all__ = ["RoaEstimate", "estimate_roa"]


@dataclass
class RoaEstimate:
    """The largest certified level ``c`` of ``{V <= c}`` and its simulation check.

    Attributes
    ----------
    level : float
        ``Vdot < 0`` was found on ``{V <= level}`` away from the equilibrium (no counterexample by
        sampling and IPOPT; ``proved`` when the check was exact).
    status : str
        The Lyapunov check's status at ``level``.
    bounded_by : str
        ``"counterexample"`` (a state with ``Vdot >= 0`` just above ``level``), ``"box"`` (the level
        set reaches the region's boundary) or ``"simulation"`` (a simulated start inside the
        level set did not converge; the level was lowered below where it ended).
    counterexample : ndarray or None
        The counterexample that bounds the level, if any.
    simulated, converged, monotone : int
        Starts sampled in ``{V <= level}``; how many ended below ``1e-3 * level``; how many had
        ``V`` non-increasing at every step.
    """

    level: float
    status: str
    bounded_by: str
    counterexample: np.ndarray | None
    simulated: int
    converged: int
    monotone: int
    details: dict[str, Any] = field(default_factory=dict)

    @property
    def confirmed(self) -> bool:
        """Every simulated start converged with ``V`` non-increasing."""
        return self.simulated > 0 and self.converged == self.monotone == self.simulated

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary."""
        return {"level": self.level, "status": self.status, "bounded_by": self.bounded_by,
                "counterexample": None if self.counterexample is None
                else self.counterexample.tolist(),
                "simulated": self.simulated, "converged": self.converged,
                "monotone": self.monotone, "confirmed": self.confirmed, "details": self.details}


def estimate_roa(
    model: Model,
    V=None,
    *,
    target: Sequence[float],
    region: Mapping[str, Sequence[float]] | Box,
    params: Mapping[str, float] | None = None,
    seed: int = 0,
    rtol: float = 1e-3,
    samples: int = 20_000,
    confirm: int = 200,
    horizon: float | None = None,
) -> RoaEstimate:
    """Estimate the region of attraction of ``target`` as a sublevel set ``{V <= c}``.

    Bisection on ``c`` between 0 and the smallest ``V`` on the region's boundary (so that the
    level set stays inside the region): each candidate level is checked with
    :func:`check_lyapunov` (sampling + multistart IPOPT). The final level is re-checked with
    ``>= 1e5`` samples, then ``confirm`` starts sampled inside it are simulated with the model's
    batched rollout for ``horizon`` seconds to confirm convergence and monotone decrease; a start
    that does not converge lowers the level below ``V`` where it ended, and the check repeats.

    Parameters
    ----------
    rtol : float
        Bisection stops when the bracket is narrower than ``rtol`` times the upper bound.
    samples : int
        Samples per bisection step.
    confirm : int
        Number of simulated starts.
    horizon : float, optional
        Simulated time (default: ``20 / (smallest decay rate seen)``, capped at 10000 steps).
    """
    orig = model
    if params:
        model = model.with_params(**params)
        if isinstance(V, cs.SX):          # built from the caller's model.sym: move it over
            V = _candidate(model, V, orig)
    box = as_box(model, region)
    _, v_num, _, _, _ = lyapunov_functions(model, V, target=target)
    vfun = cs.Function("V", [model.sym.x], [v_num])
    rng = np.random.default_rng(seed)
    step = _discrete_check(model, vfun, v_num, box, target, rng)
    c_box = _min_on_boundary(model, vfun, box, rng)
    check: dict[str, Any] = {"target": target, "region": box, "seed": seed}
    _, _, _, v_sym, _ = lyapunov_functions(model, V, target=target)
    if is_gradient_flow(model, v_sym):     # its stationary points, found once for every level
        check["equilibria"] = find_equilibria(model, target=target, region=box, seed=seed)
    full = check_lyapunov(model, V, level=c_box, **check)
    if full.status != "counterexample":
        level, status, bounded, cex = c_box, full.status, "box", None
    else:
        lo, hi, cex = 0.0, c_box, full.counterexample
        status = "no_counterexample"
        while hi - lo > rtol * hi:
            mid = (lo + hi) / 2
            try:
                rep = check_lyapunov(model, V, level=mid, samples=samples, starts=8, **check)
            except HybridnavError as exc:   # no sampled state below a tiny level: go up
                log.debug("level %g: %s", mid, exc)
                lo = mid
                continue
            if rep.status == "counterexample":
                hi, cex = mid, rep.counterexample
            else:
                lo, status = mid, rep.status
        level, bounded = lo, "counterexample"
        if level > 0:
            status = check_lyapunov(model, V, level=level, **check).status
    sim = _confirm(model, vfun, box, target, level, confirm, rng, horizon) if level > 0 else {}
    for _ in range(5):
        # a start inside {V <= level} that did not converge ended near a state with Vdot >= 0
        # that the search missed: lower the level below V there and confirm again
        stuck = sim.get("stuck_V")
        if stuck is None or not len(stuck):
            break
        bounded, cex = "simulation", sim["stuck_state"]
        level = float(np.min(stuck)) * (1 - rtol)
        status = check_lyapunov(model, V, level=level, **check).status
        sim = _confirm(model, vfun, box, target, level, confirm, rng, horizon)
    return RoaEstimate(level=float(level), status=status, bounded_by=bounded, counterexample=cex,
                       simulated=sim.get("simulated", 0), converged=sim.get("converged", 0),
                       monotone=sim.get("monotone", 0),
                       details={"boundary_level": float(c_box), "discrete_step": step,
                                **sim.get("details", {})})


def _discrete_check(model, vfun, v_num, box: Box, target, rng) -> dict[str, Any]:
    """The simulated step at the equilibrium (the minimizer of V); refuse when it is unstable:
    simulations that confirm a level would then only show the integrator diverging."""
    from hybridnav.analysis.linearize import discrete_step
    from hybridnav.analysis.lyapunov import _minimize_v

    pts = box.sample(4000, rng)
    v = np.asarray(vfun.map(len(pts))(pts.T)).ravel()
    ok = np.isfinite(v) & model.admissible(pts)
    if not ok.any():
        return {"status": "not_checked", "reason": "no finite V sampled"}

    x_star = _minimize_v(model, vfun, v_num, box, None, pts, v, ok, 8)
    try:
        rep = discrete_step(model, x_star, target)
    except (HybridnavError, RuntimeError) as exc:
        return {"status": "not_differentiable", "reason": str(exc), "point": x_star.tolist()}
    if not rep.stable:
        raise HybridnavError(
            f"model {model.name}: the simulated step (RK4, dt = {model.dt:g}) is unstable at "
            f"the equilibrium {np.round(x_star, 6).tolist()} (spectral radius "
            f"{rep.spectral_radius:.4g} >= 1): simulated runs diverge whatever the continuous "
            "system does; lower dt or the gains before estimating a region of attraction")
    return {"status": "stable", **rep.to_dict()}


def _min_on_boundary(model, vfun: cs.Function, box: Box, rng, per_face: int = 4000) -> float:
    """The smallest ``V`` sampled on the box faces of the position coordinates."""
    pts = []
    for d in range(min(2, len(box.names))):
        for bound in (box.lower[d], box.upper[d]):
            P = box.sample(per_face, rng)
            P[:, d] = bound
            pts.append(P)
    P = np.vstack(pts)
    v = np.asarray(vfun.map(len(P))(P.T)).ravel()
    return float(np.min(v[np.isfinite(v) & model.admissible(P)]))


def _confirm(model, vfun, box: Box, target, level, n, rng, horizon) -> dict[str, Any]:
    starts = []
    tries = 0
    while sum(len(s) for s in starts) < n and tries < 200:
        P = box.sample(max(4 * n, 1000), rng)
        v = np.asarray(vfun.map(len(P))(P.T)).ravel()
        starts.append(P[np.isfinite(v) & (v <= level) & model.admissible(P)])
        tries += 1
    X0 = np.vstack(starts)[:n]
    if not len(X0):
        return {}
    tgt = np.tile(np.asarray(target, dtype=float), (len(X0), 1))
    X0 = model.retarget(X0, tgt)
    steps = 10_000 if horizon is None else int(np.ceil(horizon / model.dt))
    traj = model.rollout(X0, tgt, min(steps, 10_000))
    flat = traj.reshape(-1, model.nx)
    V = np.asarray(vfun.map(len(flat))(flat.T)).reshape(len(X0), -1)
    slack = 1e-9 * max(level, 1e-300)
    monotone = np.all(np.diff(V, axis=1) <= slack, axis=1)
    converged = V[:, -1] <= 1e-3 * level
    lowest = int(np.argmin(np.where(converged, np.inf, V[:, -1])))
    return {"stuck_V": V[~converged, -1], "stuck_state": traj[lowest, -1],
            "simulated": len(X0), "converged": int(converged.sum()),
            "monotone": int(monotone.sum()),
            "details": {"simulated_time": float(traj.shape[1] - 1) * model.dt,
                        "worst_final_V": float(np.max(V[:, -1]))}}
