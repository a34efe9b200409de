"""Region-of-attraction estimates from Lyapunov level sets, confirmed by batched simulation."""

from __future__ import annotations

import logging
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import casadi as cs
import numpy as np

from hybridnav.analysis.equilibria import resolve
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
from hybridnav.models.compile import evaluate_rows

log = logging.getLogger(__name__)

__all__ = ["RoaEstimate", "basin", "basin_share", "estimate_roa", "lyapunov_equation_candidate"]


@dataclass
class RoaEstimate:
    """The largest certified level ``c`` of ``{V <= c}`` and its simulation check.

    Attributes
    ----------
    level : float
        ``Vdot < 0`` was found on ``{V <= level}`` away from the equilibrium (no counterexample by
        sampling and IPOPT; ``proved`` when the quadratic route or the certificate closed);
        ``inf`` when the proof is global.
    status : str
        The Lyapunov check's status at ``level``.
    bounded_by : str
        ``"none"`` (global proof), ``"counterexample"`` (a state with ``Vdot >= 0`` just above
        ``level``), ``"equilibrium"`` (an equilibrium other than the target at ``V`` just above
        ``level``), ``"box"`` (the level set reaches the boundary of the region, grown as far as
        allowed) or ``"simulation"`` (a simulated start inside the
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
        return {"level": self.level if np.isfinite(self.level) else None, "status": self.status, "bounded_by": self.bounded_by,
                "counterexample": None if self.counterexample is None
                else self.counterexample.tolist(),
                "simulated": self.simulated, "converged": self.converged,
                "monotone": self.monotone, "confirmed": self.confirmed, "details": self.details}


def estimate_roa(
    model: Model,
    V=None,
    *,
    target: Sequence[float] | None = None,
    region: Mapping[str, Sequence[float]] | Box,
    equilibrium: Sequence[float] | None = None,
    params: Mapping[str, float] | None = None,
    seed: int = 0,
    rtol: float = 1e-3,
    samples: int = 20_000,
    confirm: int = 200,
    horizon: float | None = None,
    grow: int = 4,
    certificate: bool | None = None,
) -> RoaEstimate:
    """Estimate the region of attraction of ``target`` as a sublevel set ``{V <= c}``.

    1. When ``V`` is proved a Lyapunov function on the whole state space (the quadratic route),
       the level is unbounded: ``level = inf``, ``bounded_by = "none"``.
    2. Otherwise the level is bounded by what the sublevel set must not contain: states with
       ``Vdot >= 0`` (bisection on ``c`` with :func:`check_lyapunov`, sampling + multistart IPOPT)
       and equilibria other than the target (:func:`find_equilibria`: below the lowest ``V`` of
       one). The region is only where the search looks: the models are defined beyond it, so
       where the level set would reach the region's boundary the position bounds are doubled
       about the target (up to ``grow`` times) before the boundary caps the level
       (``bounded_by = "box"``).
    3. The final level is checked with the certificate route (interval branch and bound), so its
       status is ``proved`` when the certificate closes (when it does not, 99, 90, 70 and 50 % of
       the level are tried, and the first one proved is reported, the sampled level kept in
       ``details["lowered_to_prove"]``); then ``confirm`` starts sampled inside it
       are simulated with the model's batched rollout for ``horizon`` seconds to confirm
       convergence and monotone decrease; a start that does not converge lowers the level below
       ``V`` where it ended, and the check repeats.

    Parameters
    ----------
    model : Model or any system :func:`~hybridnav.analysis.as_system` takes
    V : casadi.SX, callable or None
        The Lyapunov candidate (as :func:`hybridnav.analysis.check_lyapunov` accepts it; None:
        the model's own).
    target : (float, float), optional
        A robot model's target.
    region : dict or Box
        Bounds of every state the estimate is taken in.
    equilibrium : array_like, optional
        A general system's equilibrium state (default: the one it was built with).
    params : dict, optional
        Model parameters overriding the model's values.
    seed : int
        Seeds the sampling and the simulated starts.
    rtol : float
        Bisection stops when the bracket is narrower than ``rtol`` times the upper bound; levels
        below an equilibrium's ``V`` are that ``V`` times ``1 - rtol``.
    samples : int
        Samples per bisection step.
    confirm : int
        Number of simulated starts.
    horizon : float, optional
        Simulated time (default: 10000 control cycles).
    grow : int
        How many times the position bounds may double about the target.
    certificate : bool, optional
        Check the final level with the certificate route (default: up to 3 states).

    Returns
    -------
    RoaEstimate
        ``details["region"]`` is the region the level refers to (grown or not).
    """
    model, target = resolve(model, target, equilibrium)
    _check_roa_settings(rtol=rtol, samples=samples, confirm=confirm, grow=grow, horizon=horizon)
    orig = model
    if params:
        model = model.with_params(**params)
        if isinstance(V, cs.SX):          # built from the caller's model.sym: move it over
            V = _candidate(model, V, orig)
    box = as_box(model, region)
    _, v_num, vdot_num, v_sym, _ = lyapunov_functions(model, V, target=target)
    vfun = cs.Function("V", [model.sym.x], [v_num])
    rng = np.random.default_rng(seed)
    step = _discrete_check(model, vfun, v_num, box, target, rng)
    details: dict[str, Any] = {"discrete_step": step}
    check: dict[str, Any] = {"target": target, "seed": seed}
    full = _quadratic_proof(model, v_num, vdot_num, box, target)
    if full is not None:
        sim = _confirm(model, vfun, box, target, np.inf, confirm, rng, horizon)
        details.update(region=box.to_dict(), claim=full.claim, **sim.get("details", {}))
        return RoaEstimate(level=np.inf, status="proved", bounded_by="none", counterexample=None,
                           simulated=sim.get("simulated", 0), converged=sim.get("converged", 0),
                           monotone=sim.get("monotone", 0), details=details)
    grad_flow = is_gradient_flow(model, v_sym)
    c_box = _min_on_boundary(model, vfun, box, rng)
    eqs = find_equilibria(model, target=target, region=box, seed=seed)
    c_eq = _lowest_other(eqs, vfun)
    grown = 0
    while grown < grow and c_box < c_eq:
        wider = _doubled(box, target)
        c_wide = _min_on_boundary(model, vfun, wider, rng)
        if not c_wide > c_box * (1 + rtol):
            break
        box, c_box, grown = wider, c_wide, grown + 1
    if grown:                            # the grown region may hold other equilibria
        eqs = find_equilibria(model, target=target, region=box, seed=seed)
        c_eq = _lowest_other(eqs, vfun)
    details.update(boundary_level=float(c_box), grown=grown, region=box.to_dict())
    if np.isfinite(c_eq):
        details["equilibrium_level"] = float(c_eq)
    check["region"] = box
    if grad_flow:
        check["equilibria"] = eqs
    top = min(c_box, c_eq * (1 - rtol))
    bounded = "box" if c_box <= c_eq * (1 - rtol) else "equilibrium"
    cex = None if bounded == "box" else min(
        (e for e in eqs if not e.is_target), key=lambda e: _v_at(vfun, e.state)).state
    if not top > 0:
        # another equilibrium where V <= 0 (V is not positive definite there): every sublevel
        # set {V <= c}, c > 0, holds it, so none is a region of attraction of the target
        details["not_proved"] = (f"V = {float(c_eq):.6g} <= 0 at the equilibrium "
                                 f"{np.asarray(cex).tolist()}, not the target: no level")
        return RoaEstimate(level=0.0, status="counterexample", bounded_by="equilibrium",
                           counterexample=cex, simulated=0, converged=0, monotone=0,
                           details=details)
    first = check_lyapunov(model, V, level=top, certificate=False, **check)
    level, status = top, first.status
    if first.status == "counterexample":
        lo, hi, cex = 0.0, top, first.counterexample
        status = "no_counterexample"
        while hi - lo > rtol * hi:
            mid = (lo + hi) / 2
            try:
                rep = check_lyapunov(model, V, level=mid, samples=samples, starts=8,
                                     certificate=False, **check)
            except HybridnavError as exc:   # no sampled state below a tiny level: go up
                log.debug("level %g: %s", mid, exc)
                lo = mid
                continue
            if rep.status == "counterexample":
                hi, cex = mid, rep.counterexample
            else:
                lo, status = mid, rep.status
        level, bounded = lo, "counterexample"
    final, tried = None, []
    for k in range(FINAL_TRIES):
        if not level > 0:
            break
        try:
            final = check_lyapunov(model, V, level=level, certificate=certificate, **check)
        except HybridnavError as exc:       # no sampled state below a tiny level: stop here
            log.debug("level %g: %s", level, exc)
            break
        status = final.status
        tried.append(float(level))
        if status != "counterexample":
            break
        # the certificate found what the bisection's sampling missed: go below it, and from the
        # fourth try on ever faster (4 rtol, 16 rtol ... of the level, at most half) where its
        # counterexamples creep down a hair at a time along the set where Vdot = 0
        cex, bounded = final.counterexample, "counterexample"
        below = final.details.get("counterexample_V", level) * (1 - rtol)
        level = min(below, level * (1 - min(0.5, rtol * 4.0 ** max(0, k - 2))))
    if status == "counterexample":
        # every level tried (down to tried[-1]) holds a state with Vdot >= 0, but the levels
        # below it are untried: no sublevel set is certified, and none is refuted
        level, status = 0.0, "undecided"
        details["not_proved"] = (f"the certificate found a state with Vdot >= 0 in {{V <= c}} "
                                 f"at each of {len(tried)} levels c from {tried[0]:.6g} down to "
                                 f"{tried[-1]:.6g}")
    if (final is not None and status in ("no_counterexample", "undecided") and level > 0
            and (certificate if certificate is not None else model.nx <= 3)):
        # the sampled level is not proved (it may sit a hair above the largest valid level,
        # where Vdot > 0 on a sliver no sample hit): the largest of a few lower levels that is
        # (a quarter of the default budget per try: a level that closes closes quickly)
        for frac in (0.99, 0.9, 0.7, 0.5):
            rep = check_lyapunov(model, V, level=level * frac, certificate=True,
                                 max_boxes=25_000, **check)
            if rep.status == "proved":
                details["lowered_to_prove"] = {"from": float(level), "fraction": frac}
                level, status, final = level * frac, "proved", rep
                break
    dfun = cs.Function("Vdot", [model.sym.x], [vdot_num])
    sim = (_confirm(model, vfun, box, target, level, confirm, rng, horizon, dfun)
           if level > 0 else {})
    for _ in range(5):
        # a start inside {V <= level} that did not converge ended near a state with Vdot >= 0,
        # or V rose along it where Vdot >= 0: a state the search missed; lower the level below
        # V there and confirm again
        stuck, rise = sim.get("stuck_V", np.empty(0)), sim.get("rise_V", np.empty(0))
        if not len(stuck) and not len(rise):
            break
        if len(rise) and (not len(stuck) or rise.min() < stuck.min()):
            cex, low = sim["rise_state"], float(rise.min())
        else:
            cex, low = sim["stuck_state"], float(stuck.min())
        bounded = "simulation"
        level = low * (1 - rtol)
        if not (np.isfinite(level) and level > 0):
            # the run ended where V is not a number or at V = 0: no level is certified
            level, status = 0.0, "counterexample"
            break
        final = check_lyapunov(model, V, level=level, certificate=certificate, **check)
        status = final.status
        sim = _confirm(model, vfun, box, target, level, confirm, rng, horizon, dfun)
    if final is not None:
        details.update(claim=final.claim, route=final.route, method=final.method)
        cert = final.details.get("certificate", {})
        if status == "proved" and final.route == "certificate" and cert.get("invariant") is not True:
            # V decreases on the set, but the set was not shown invariant: not a region of
            # attraction
            status = "no_counterexample"
            details["not_proved"] = ("the certificate showed V > 0 > Vdot on {V <= level} but not "
                                     "that the set is positively invariant: "
                                     + cert.get("details", {}).get("invariance_refused",
                                                                   "faces undecided"))
        if status == "proved" and final.route == "lasalle":
            # LaSalle's claim is that trajectories enter {V < eps}, which may hold other
            # attractors: not that they converge to the equilibrium
            status = "no_counterexample"
            details["not_proved"] = ("LaSalle's route shows that trajectories from the set enter "
                                     "{V < eps}, not that they converge to the equilibrium")
    return RoaEstimate(level=float(level), status=status, bounded_by=bounded, counterexample=cex,
                       simulated=sim.get("simulated", 0), converged=sim.get("converged", 0),
                       monotone=sim.get("monotone", 0),
                       details={**details, **sim.get("details", {})})


#: certificate checks of the final level, each below the last one's counterexample
FINAL_TRIES = 12


def _check_roa_settings(*, rtol, samples, confirm, grow, horizon) -> None:
    """Refuse settings estimate_roa cannot use, naming the key."""
    if isinstance(rtol, bool) or not isinstance(rtol, (int, float)) or not 0 < rtol < 1:
        raise HybridnavError(f"rtol: expected a number in (0, 1), got {rtol!r}")
    for key, v, low in (("samples", samples, 1), ("confirm", confirm, 0), ("grow", grow, 0)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < low:
            raise HybridnavError(f"{key}: expected an integer >= {low}, got {v!r}")
    if horizon is not None and (isinstance(horizon, bool)
                                or not isinstance(horizon, (int, float))
                                or not (np.isfinite(horizon) and horizon > 0)):
        raise HybridnavError(f"horizon: expected a number > 0, got {horizon!r}")


def _check_grid(model, n, fixed) -> None:
    if model.nx < 2:
        raise HybridnavError(f"model {model.name}: a basin grid needs two states, it has "
                             f"{model.nx}")
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2:
        raise HybridnavError(f"n: expected an integer >= 2, got {n!r}")
    for key, value in (fixed or {}).items():
        if key not in model.state_names:
            raise HybridnavError(f"fixed.{key}: not a state of {model.name}; expected one of: "
                                 + ", ".join(model.state_names))
        try:
            ok = np.isfinite(float(value))
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise HybridnavError(f"fixed.{key}: expected a finite number, got {value!r}")


def _quadratic_proof(model, v_num, vdot_num, box: Box, target):
    """The quadratic route's report when it proves V globally, else None."""
    from hybridnav.analysis.quadratic import _quadratic_argument
    from hybridnav.analysis.verdict import LyapunovReport

    rep = LyapunovReport("no_counterexample", "", "", None, -np.inf, None, "")
    from hybridnav.analysis.lyapunov import _target_state

    if _quadratic_argument(model, v_num, vdot_num, box, None, rep,
                           center=_target_state(model, target)) and rep.status == "proved":
        return rep
    return None


def _v_at(vfun, state) -> float:
    return float(np.asarray(vfun(state)).item())


def _lowest_other(eqs, vfun) -> float:
    """The lowest V (the candidate's) at an equilibrium other than the target (inf: none)."""
    others = [_v_at(vfun, e.state) for e in eqs if not e.is_target]
    others = [v for v in others if np.isfinite(v)]
    return float(min(others)) if others else np.inf


def _doubled(box: Box, target) -> Box:
    """The box with its position bounds (the first two states; a system's every state) twice as
    far from the target (equilibrium)."""
    t = np.asarray(target, dtype=float)
    k = len(t)
    lower, upper = box.lower.copy(), box.upper.copy()
    lower[:k] = t - 2 * (t - lower[:k])
    upper[:k] = t + 2 * (upper[:k] - t)
    return Box(box.names, lower, upper)


def lyapunov_equation_candidate(model: Model, target: Sequence[float] | None = None, Q=None,
                                params: Mapping[str, float] | None = None, *,
                                equilibrium: Sequence[float] | None = None):
    """A quadratic candidate from the linearization at the target: ``V = dx' P dx``.

    ``P`` solves the Lyapunov equation ``A' P + P A = -Q`` (``control.lyap``) for the closed
    loop's Jacobian ``A`` at ``x* = target`` (the model's remaining states at 0), so that
    ``Vdot = -dx' Q dx + O(|dx|^3)`` near the target.

    Parameters
    ----------
    model : Model or any system :func:`~hybridnav.analysis.as_system` takes
    target : (2,) array_like, optional
        A robot model's target.
    Q : (nx, nx) array_like, optional
        Symmetric positive definite weight (default: the identity).
    params : dict, optional
        Parameter overrides.
    equilibrium : array_like, optional
        A general system's equilibrium state.

    Returns
    -------
    V : casadi.SX
        In ``model.sym.x`` (of ``model`` with ``params`` applied).
    P : ndarray

    Raises
    ------
    HybridnavError
        When ``A`` is not Hurwitz (no positive definite solution) or ``Q`` is not symmetric
        positive definite.
    """
    import control

    from hybridnav.analysis.linearization import linearize
    from hybridnav.analysis.lyapunov import _target_state

    model, target = resolve(model, target, equilibrium)
    if params:
        model = model.with_params(**params)
    x0 = _target_state(model, target)
    A = np.asarray(linearize(model, x0, target=target).A, dtype=float)
    try:
        Q = np.eye(model.nx) if Q is None else np.asarray(Q, dtype=float)
    except (TypeError, ValueError):
        raise HybridnavError(f"Q: expected a symmetric positive definite {A.shape} matrix, got "
                             f"{Q!r}") from None
    if Q.shape != A.shape or not np.allclose(Q, Q.T) or np.linalg.eigvalsh(Q).min() <= 0:
        raise HybridnavError(f"Q: expected a symmetric positive definite {A.shape} matrix")
    eig = np.linalg.eigvals(A)
    not_hurwitz = HybridnavError(
        f"model {model.name}: the linearization at the target is not Hurwitz (eigenvalues "
        f"{np.round(eig, 6).tolist()}): A' P + P A = -Q has no positive definite solution")
    if not np.all(eig.real < 0):
        raise not_hurwitz
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")         # scipy on a (near) zero eigenvalue pair
        P = np.asarray(control.lyap(A.T, Q), dtype=float)
    P = (P + P.T) / 2
    # an eigenvalue computed a rounding below 0 (an exact zero: a singular A) passes the test
    # above; the solution then is no positive definite solution of the equation (Lyapunov's
    # theorem: one exists exactly when A is Hurwitz), and that is what is checked
    resid = np.abs(A.T @ P + P @ A + Q).max() if np.all(np.isfinite(P)) else np.inf
    if not (resid <= 1e-8 * np.abs(Q).max() and np.linalg.eigvalsh(P).min() > 0):
        raise not_hurwitz
    dx = model.sym.x - cs.DM(x0)
    return cs.mtimes([dx.T, cs.DM(P), dx]), P


def basin(model: Model, *, target: Sequence[float] | None = None, region,
          fixed: Mapping[str, float] | None = None, n: int = 101, horizon: float | None = None,
          radius: float | None = None, method: str = "continuous",
          equilibrium: Sequence[float] | None = None):
    """The true region of attraction on a grid of the first two states, by batched simulation.

    Every grid point (the other states from ``fixed``, default 0; inadmissible points excluded)
    is simulated for ``horizon`` seconds (default ``20000 dt``); it *converged* when it ends within
    ``radius`` of the target (default 1e-3 of the region's diagonal).

    Parameters
    ----------
    model : Model or any system :func:`~hybridnav.analysis.as_system` takes
    target : (float, float), optional
        A robot model's target.
    region : dict or Box
        Bounds of the plotted states, e.g. ``{"x": (lo, hi), "y": (lo, hi)}``.
    fixed : dict, optional
        Values of the other states (default 0; a system's: the equilibrium's).
    n : int
        Grid points per axis.
    horizon : float, optional
        Simulated time per start (default ``20000 dt``).
    radius : float, optional
        A start has converged when it ends within ``radius`` of the target (default 1e-3 of the
        region's ``(x, y)`` diagonal).
    method : str
        ``"continuous"`` (default): the closed-loop ODE, the system the Lyapunov certificates are
        about, integrated by CVODES (CasADi's ``integrator``, tolerances 1e-7 relative and 1e-9
        absolute) mapped over the grid on two threads. ``"simulated"``: the model's own RK4
        control cycle at ``model.dt``, what the planners run (it can differ: large steps near
        LbCS obstacles jump where the flow would not go).
    equilibrium : array_like, optional
        A general system's equilibrium state.

    Returns
    -------
    xs, ys : (n,) arrays
    converged : (n, n) bool array, indexed ``[iy, ix]``
    """
    if method not in ("continuous", "simulated"):
        raise HybridnavError(f"method: expected 'continuous' or 'simulated', got {method!r}")
    model, target = resolve(model, target, equilibrium)
    _check_grid(model, n, fixed)
    box = as_box(model, region)
    xs = np.linspace(box.lower[0], box.upper[0], n)
    ys = np.linspace(box.lower[1], box.upper[1], n)
    X, Y = np.meshgrid(xs, ys)
    Z = np.zeros((X.size, model.nx))
    if len(target) == model.nx:          # a system: the other states at the equilibrium's
        Z[:] = target
    Z[:, 0], Z[:, 1] = X.ravel(), Y.ravel()
    for name, value in (fixed or {}).items():
        Z[:, model.state_names.index(name)] = value
    t = target
    tg = np.tile(t, (len(Z), 1))
    Z = model.retarget(Z, tg)
    r = radius if radius is not None else 1e-3 * float(np.hypot(*(box.upper[:2] - box.lower[:2])))
    T = 20_000 * model.dt if horizon is None else float(horizon)
    ok = model.admissible(Z)
    idx = np.flatnonzero(ok)
    end = np.full_like(Z, np.nan)
    if method == "continuous":
        end[idx] = _integrate(model, t, Z[idx], T)
    else:
        end[idx] = _rk4_ends(model, t, Z[idx], int(np.ceil(T / model.dt)), box, r)
    with np.errstate(invalid="ignore"):
        done = np.linalg.norm(end[:, :len(t)] - t, axis=1) <= r
    return xs, ys, (done & ok).reshape(n, n)


def _integrate(model: Model, target, Z: np.ndarray, T: float) -> np.ndarray:
    """End states of the closed-loop ODE from each row of ``Z`` after ``T`` seconds (CVODES)."""
    s = model.sym
    f = model.closed_loop_at(target)
    opts = {"abstol": 1e-9, "reltol": 1e-7, "max_num_steps": 200_000}
    integ = cs.integrator("basin", "cvodes", {"x": s.x, "ode": f}, 0.0, T, opts)
    if not len(Z):
        return Z.copy()
    try:
        return np.asarray(integ.map(len(Z), "thread", 2)(x0=Z.T)["xf"]).T
    except RuntimeError:              # one start failed (a singular state): integrate one by one
        out = np.full_like(Z, np.nan)
        for i, z in enumerate(Z):
            try:
                out[i] = np.asarray(integ(x0=z)["xf"]).ravel()
            except RuntimeError:
                pass
        return out


def _rk4_ends(model: Model, target, Z: np.ndarray, steps: int, box: Box, radius: float
              ) -> np.ndarray:
    """End states of the simulated (RK4) loop; a run that enters an inadmissible state ends
    there (NaN). Chunks of cycles; runs that arrived or stopped moving are dropped early."""
    Z = Z.copy()
    tg = np.tile(target, (len(Z), 1))
    span = float(np.max(box.upper - box.lower)) or 1.0
    r = 1e-9 * span
    active = np.arange(len(Z))
    chunk, done_steps = 200, 0
    with np.errstate(all="ignore"):
        while len(active) and done_steps < steps:
            k = min(chunk, steps - done_steps)
            traj = model.rollout(Z[active], tg[active], k)
            hit = ~model.admissible(traj.reshape(-1, model.nx)).reshape(len(active), -1).all(1)
            Z[active] = traj[:, -1]
            Z[active[hit]] = np.nan
            done_steps += k
            last = traj[:, -1]
            still = np.max(np.abs(last - traj[:, max(0, k - 100)]), axis=1) < r
            lost = hit | ~np.all(np.isfinite(last), axis=1)
            arrived = np.linalg.norm(last[:, :len(target)] - target, axis=1) <= radius
            active = active[~(still | lost | arrived)]
    return Z


def _discrete_check(model, vfun, v_num, box: Box, target, rng) -> dict[str, Any]:
    """The simulated step at the equilibrium (the minimizer of V); refuse when it is unstable:
    simulations that confirm a level would then only show the integrator diverging."""
    from hybridnav.analysis.linearization import discrete_step
    from hybridnav.analysis.lyapunov import _minimize_v

    pts = box.sample(4000, rng)
    v = evaluate_rows(vfun, pts)[0].ravel()
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
    v = evaluate_rows(vfun, P)[0].ravel()
    return float(np.min(v[np.isfinite(v) & model.admissible(P)]))


def _confirm(model, vfun, box: Box, target, level, n, rng, horizon, dfun=None
             ) -> dict[str, Any]:
    """Simulate ``n`` starts sampled in ``{V <= level}``. Runs that do not converge give
    ``stuck_V``; a run whose ``V`` rises is checked at the state before its largest rise: where the
    continuous ``Vdot`` (``dfun``) is >= 0 there it is a counterexample the search missed
    (``rise_V``, ``rise_state``), otherwise the rise is the RK4 step's (counted in details). Runs
    that RK4 takes to non-finite states are integrated again by CVODES (counted in details); one
    that fails there too is named by its start."""
    if n <= 0:
        return {}
    starts = []
    tries = 0
    while sum(len(s) for s in starts) < n and tries < 200:
        P = box.sample(max(4 * n, 1000), rng)
        v = evaluate_rows(vfun, P)[0].ravel()
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
    V = evaluate_rows(vfun, flat)[0].reshape(len(X0), -1)
    ref = level if np.isfinite(level) else float(np.max(V[:, 0]))   # global: the largest start
    slack = 1e-9 * max(ref, 1e-300)
    monotone = np.all(np.diff(V, axis=1) <= slack, axis=1)
    end, end_V = traj[:, -1].copy(), V[:, -1].copy()
    # a run that left the numbers (RK4 is unstable on a stiff or fast part of the field) says
    # nothing about the continuous system: those starts are integrated again by CVODES
    diverged = ~np.all(np.isfinite(V), axis=1)
    if diverged.any():
        end[diverged] = _integrate(model, target, X0[diverged], (traj.shape[1] - 1) * model.dt)
        end_V[diverged] = evaluate_rows(vfun, end[diverged])[0].ravel()
    # still not a number: the run's start is what the report can name, and V there what the
    # level must stay below
    lost = ~np.all(np.isfinite(end), axis=1)
    end[lost], end_V[lost] = X0[lost], V[lost, 0]
    converged = end_V <= 1e-3 * ref
    lowest = int(np.argmin(np.where(converged, np.inf, np.nan_to_num(end_V, nan=-np.inf))))
    rise_V, rise_state, step_rises = np.empty(0), None, 0
    if dfun is not None and not (monotone | diverged).all():
        rows = np.flatnonzero(~(monotone | diverged))
        k = np.argmax(np.diff(V[rows], axis=1), axis=1)
        states = traj[rows, k]
        d = evaluate_rows(dfun, states)[0].ravel()
        real = d >= 0
        step_rises = int((~real).sum())
        if real.any():
            rise_V = V[rows[real], k[real]]
            rise_state = states[np.flatnonzero(real)[np.argmin(rise_V)]]
    return {"stuck_V": end_V[~converged], "stuck_state": end[lowest],
            "rise_V": rise_V, "rise_state": rise_state,
            "simulated": len(X0), "converged": int(converged.sum()),
            "monotone": int(monotone.sum()),
            "details": {"simulated_time": float(traj.shape[1] - 1) * model.dt,
                        "worst_final_V": float(np.max(end_V)),
                        "rises_of_the_rk4_step": step_rises,
                        "rk4_diverged_cvodes_rerun": int(diverged.sum())}}


def basin_share(model: Model, V=None, level: float = np.inf, *,
                target: Sequence[float] | None = None, region,
                equilibrium: Sequence[float] | None = None, n: int = 201,
                horizon: float | None = None, method: str = "simulated") -> dict[str, float]:
    """How much of the true region of attraction a certified level set covers, on a grid of the
    first two states (the others at the target's / equilibrium's values).

    The true basin is :func:`basin` (CVODES from every grid point); the certified set is
    ``{V <= level}``. Areas are grid-cell counts times the cell area.

    Parameters
    ----------
    model : Model or any system :func:`~hybridnav.analysis.as_system` takes
    V : casadi.SX, callable or None
        The candidate (None: the model's own).
    level : float
        The certified level (e.g. ``estimate_roa(...).level``).
    target, equilibrium : array_like, optional
        As for :func:`estimate_roa`.
    region : dict or Box
        The grid's bounds (every state).
    n : int
        Grid points per axis.
    horizon : float, optional
        Simulated time per start (see :func:`basin`).
    method : str
        :func:`basin`'s: ``"simulated"`` (default; RK4 at ``model.dt``, runs that diverge are
        dropped early) or ``"continuous"`` (CVODES, slow where many starts diverge).

    Returns
    -------
    dict
        ``certified_area``, ``basin_area``, ``share`` (certified / basin) and
        ``certified_in_basin`` (the fraction of certified grid points that converged: 1 unless
        the certificate or the simulation is wrong).
    """
    model, target = resolve(model, target, equilibrium)
    _, v_num, _, _, _ = lyapunov_functions(model, V, target=target)
    xs, ys, conv = basin(model, target=target, region=region, n=n, horizon=horizon,
                         method=method)
    box = as_box(model, region)
    X, Y = np.meshgrid(xs, ys)
    Z = np.zeros((X.size, model.nx))
    if len(target) == model.nx:
        Z[:] = target
    Z[:, 0], Z[:, 1] = X.ravel(), Y.ravel()
    vfun = cs.Function("V", [model.sym.x], [v_num])
    v = evaluate_rows(vfun, Z)[0].reshape(n, n)
    cert = np.isfinite(v) & (v <= level)
    cell = float((box.upper[0] - box.lower[0]) * (box.upper[1] - box.lower[1])) / (n - 1) ** 2
    basin_area = float(conv.sum()) * cell
    cert_area = float(cert.sum()) * cell
    return {"certified_area": cert_area, "basin_area": basin_area,
            "share": cert_area / basin_area if basin_area else float("nan"),
            "certified_in_basin": float((cert & conv).sum() / cert.sum()) if cert.any()
            else float("nan")}
