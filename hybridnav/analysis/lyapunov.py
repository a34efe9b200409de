"""Lyapunov checks of closed-loop models, and their equilibria.

:func:`check_lyapunov` decides, for a candidate ``V`` and a region, one of three statuses:

``"proved"``
    Only from an exact argument, and ``report.claim`` says what was proved on which set:

    - *quadratic*: ``V`` and ``Vdot`` are quadratic forms (checked symbolically with
      ``casadi.is_quadratic``) about the same point, with constant Hessians that are positive and
      negative definite beyond a tolerance, so ``V > 0`` and ``Vdot < 0`` everywhere else;
    - *certificate*: interval branch and bound over the region (or level set) proves ``V > 0`` and
      ``Vdot < 0`` on it, with a small box around the equilibrium handled by interval bounds on
      the Hessians (:func:`hybridnav.analysis.certificate.certify`); non-quadratic ``V`` included;
    - *lasalle*: ``Vdot`` is zero somewhere away from the equilibrium (so not a strict Lyapunov
      function), but branch and bound proves ``Vdot <= 0`` and that no trajectory can stay where
      ``Vdot = 0`` (a Lie derivative of ``Vdot`` is nonzero there), so by LaSalle's invariance
      principle trajectories from the set end near ``V = 0``; the ``Vdot = 0`` state is kept in
      ``details["vdot_zero_state"]``.
``"counterexample"``
    A concrete state in the region, away from the equilibrium, with ``Vdot >= 0`` — found by
    dense sampling, by a multistart IPOPT search maximizing ``Vdot``, from an indefinite quadratic
    form, or (for gradient flows such as LbCS) at a stationary point other than the target, where
    ``Vdot = 0`` exactly.
``"no_counterexample"``
    Neither: sampling (>= 1e5 states through a mapped CasADi function) and the search found none,
    and the certificate route (run by default for up to 3 states) could not decide within its
    budget. This is evidence, never a proof.
``"undecided"``
    Rounding would decide: a quadratic form's Hessian has an eigenvalue within ``tol`` of zero
    (relative to its largest entry), so neither definiteness nor a counterexample can be claimed
    from floating-point eigenvalues; the report gives the eigenvalues.

Both conditions are checked on every route: ``V > 0`` (a sampled or optimized state with
``V < 0`` is a counterexample) and ``Vdot < 0``, including near the equilibrium, where the
sampling leaves out states with ``V < exclude * max V``: there the local quadratic parts of ``V``
and ``Vdot`` (their Hessians at the minimizer of ``V``) are checked, and a Hessian of ``V`` with a
negative eigenvalue or of ``Vdot`` with a positive one (beyond ``tol``) gives a counterexample a
small step along that eigenvector — re-evaluated, with its ``V`` and ``Vdot`` printed. Every
reported counterexample is re-evaluated.

For gradient flows ``xdot_i = -c_i dV/dx_i`` with ``c_i > 0`` (the LbCS model), the identity
``Vdot = -sum_i c_i (dV/dx_i)^2 <= 0`` is established symbolically (``casadi.is_equal`` on the
expression graphs) and reported as ``vdot_nonpositive_proved``; strict decrease then fails exactly
at the stationary points, which :func:`find_equilibria` locates.
"""

from __future__ import annotations

import inspect
import logging
from collections.abc import Mapping, Sequence

import casadi as cs
import numpy as np

from hybridnav.analysis.equilibria import (
    Equilibrium,
    _target,
    find_equilibria,
    resolve,
    verify_zero,
)
from hybridnav.analysis.quadratic import _quadratic_argument
from hybridnav.analysis.region import Box, as_box
from hybridnav.analysis.verdict import LyapunovReport, _counterexample
from hybridnav.analysis.witness import Witness
from hybridnav.errors import HybridnavError
from hybridnav.models.base import Model
from hybridnav.models.compile import evaluate_rows

log = logging.getLogger(__name__)

__all__ = ["Equilibrium", "LyapunovReport", "check_lyapunov", "find_equilibria", "lyapunov_functions"]

_IPOPT = {"ipopt.print_level": 0, "ipopt.sb": "yes", "print_time": False, "ipopt.max_iter": 300,
          "ipopt.tol": 1e-10}


def lyapunov_functions(model: Model, V=None, *, target=None,
                       params: Mapping[str, float] | None = None, equilibrium=None):
    """Numeric CasADi functions ``x -> (V, Vdot)`` and the symbolic expressions behind them.

    Parameters
    ----------
    model : Model or any system :func:`~hybridnav.analysis.as_system` takes
    V : casadi.SX, callable or None
        The candidate (None: the model's own, :meth:`Model.lyapunov_candidate`).
    target : (float, float), optional
        A robot model's target.
    params : dict, optional
        Model parameters overriding the model's values.
    equilibrium : array_like, optional
        A general system's equilibrium state.

    Returns
    -------
    model : Model
        The model with ``params`` applied.
    V, Vdot : casadi.SX
        Symbolic in the state only (target and parameters substituted).
    V_sym, Vdot_sym : casadi.SX
        With the parameter and target symbols kept (for printing).
    """
    model, target = resolve(model, target, equilibrium)
    orig = model
    if params:
        model = model.with_params(**params)
    s = model.sym
    v_sym = _candidate(model, V, orig)
    vdot_sym = cs.jtimes(v_sym, s.x, model.closed_loop())
    keep = cs.vertcat(s.target, s.p)
    values = cs.DM(np.concatenate([target, model.p_value()]))
    v_num = cs.substitute(v_sym, keep, values)
    vdot_num = cs.substitute(vdot_sym, keep, values)
    return model, v_num, vdot_num, v_sym, vdot_sym


def check_lyapunov(
    model: Model,
    V=None,
    *,
    target: Sequence[float] | None = None,
    region: Mapping[str, Sequence[float]] | Box,
    equilibrium: Sequence[float] | None = None,
    level: float | None = None,
    params: Mapping[str, float] | None = None,
    seed: int = 0,
    samples: int = 100_000,
    starts: int = 16,
    exclude: float = 1e-6,
    equilibria: Sequence[Equilibrium] | None = None,
    certificate: bool | None = None,
    max_boxes: int = 100_000,
) -> LyapunovReport:
    """Check that ``V`` decreases along the closed loop of ``model`` driving to ``target``.

    Parameters
    ----------
    model : Model or any system
        A closed-loop model from :func:`hybridnav.models.get`, or a python-control ``nlsys``, a
        CasADi ``Function``, ``(x, u, rhs)`` expressions or a do-mpc model (see
        :func:`hybridnav.analysis.as_system`).
    V : casadi.SX or callable, optional
        The candidate, an expression in ``model.sym.x`` (and optionally ``model.sym.target`` and
        ``model.sym.p``) or a callable ``V(x)`` / ``V(x, target)`` returning one. Default: the
        model's own candidate (``1/2`` squared distance to the target or equilibrium; ``L`` for
        LbCS).
    target : (2,) array_like, optional
        A robot model's target point ``(x1, y1)``; the equilibrium is where ``V`` vanishes.
    region : dict or Box
        ``{state: (lo, hi)}`` for every state of the model.
    equilibrium : array_like, optional
        A general system's equilibrium state (default: the one it was built with).
    level : float, optional
        Restrict the region to ``{V <= level}``.
    params : dict, optional
        Parameter overrides for the model (e.g. ``{"alpha1": -0.1}``).
    seed : int
        Seed of the sampling and of the optimizer's starting points.
    samples : int
        Number of states sampled uniformly in the box (>= 1e5 by default).
    starts : int
        Number of IPOPT starts (half from the worst samples, half random).
    exclude : float
        States with ``V < exclude * max V`` count as "at the equilibrium" and are left out.
    equilibria : list of Equilibrium, optional
        For gradient flows: the stationary points, when already known (from
        :func:`find_equilibria` on the same model, target and region); found here otherwise.
    certificate : bool, optional
        Run the certificate route (:func:`hybridnav.analysis.certificate.certify`) when sampling
        and the search find no counterexample, and LaSalle's route when ``Vdot`` only reaches
        zero. Default: for models with at most 3 states.
    max_boxes : int
        Budget of the certificate route (boxes evaluated).

    Returns
    -------
    LyapunovReport
    """
    model, target = resolve(model, target, equilibrium)
    model, v_num, vdot_num, v_sym, vdot_sym = lyapunov_functions(model, V, target=target,
                                                                 params=params)
    box = as_box(model, region)
    _check_settings(model, box, target, level=level, samples=samples, starts=starts,
                    exclude=exclude, max_boxes=max_boxes)
    x = model.sym.x
    report = LyapunovReport(status="no_counterexample", V=_pretty(v_sym), vdot=_pretty(vdot_sym),
                            counterexample=None, worst_vdot=-np.inf, worst_state=None, method="")
    if _quadratic_argument(model, v_num, vdot_num, box, level, report,
                           center=_target_state(model, target)):
        return report
    grad_flow = is_gradient_flow(model, v_sym)
    rng = np.random.default_rng(seed)
    both = cs.Function("v_vdot", [x], [v_num, vdot_num])

    # 1) dense sampling through one mapped CasADi call (concentrated on {V <= level} when that is
    # a small part of the box)
    pts, v_s, d_s = _sample(both, box, level, int(samples), rng)
    finite_v = np.isfinite(v_s)
    top = np.max(v_s[finite_v]) if finite_v.any() else 1.0
    v_floor = exclude * (top if level is None else min(top, level))
    admissible = model.admissible(pts)
    # V > 0: a state with V < 0 contradicts positivity (checked before the floor drops it); a
    # negative floating-point value is claimed only where V's interval enclosure is negative
    witness = Witness(x, v_num, vdot_num)
    in_level = np.ones(len(pts), dtype=bool) if level is None else v_s <= level
    negative = np.flatnonzero(finite_v & admissible & in_level & (v_s < 0))
    if len(negative):
        worst = negative[np.argsort(v_s[negative])][:64]
        sure = worst[witness.v_negative(pts[worst])]
        if len(sure):
            report.route = "sampling"
            return _counterexample(report, both, pts[sure[0]], "dense sampling: V < 0 at this "
                                   "state, so V is not positive definite", witness)
    xmin = _minimize_v(model, lambda z: both(z)[0], v_num, box, level, pts, v_s,
                       finite_v & admissible, starts)
    for z, how in ((xmin, "multistart IPOPT minimizing V"),
                   (_equilibrium_guess(model, both, xmin, target, box), "at the equilibrium")):
        if witness.v_negative(z)[0]:
            report.route = "ipopt"
            return _counterexample(report, both, z, f"{how}: V < 0 at this state, so V is not "
                                   "positive definite", witness)
    local = _local_check(model, v_num, vdot_num, both, xmin, box, level, report, witness)
    if local is not None:
        report.route = "local"
        return _counterexample(report, both, local[0], local[1], witness)
    keep = finite_v & (v_s >= v_floor) & admissible
    if level is not None:
        keep &= v_s <= level
    nan = int(np.sum(keep & np.isnan(d_s)))
    keep &= ~np.isnan(d_s)
    report.details.update(samples=int(samples), samples_in_region=int(keep.sum()),
                          nan_vdot_samples=nan, v_floor=v_floor, level=level,
                          region=box.to_dict(), target=list(map(float, _target(target, model))))
    if not keep.any():
        raise HybridnavError(
            "region: no sampled state lies in the region away from the equilibrium "
            f"(level {level!r}); widen the box or raise the level"
        )
    P, D = pts[keep], d_s[keep]
    i = int(np.argmax(D))
    best_d, best_x, how = float(D[i]), P[i].copy(), "dense sampling"

    # 2) for gradient flows: Vdot <= 0 exactly; equality at stationary points other than the target
    if grad_flow:
        report.vdot_nonpositive_proved = True
        eqs = equilibria if equilibria is not None else find_equilibria(
            model, target=target, region=box, seed=seed)
        # (the level is the user's candidate's: e.V is the model's own)
        others = [e for e in eqs if not e.is_target and (
            level is None or float(np.asarray(both(e.state)[0]).item()) <= level)]
        report.details["stationary_points"] = [e.to_dict() for e in others]
        # a stationary point is claimed only where the Krawczyk test proves one in a small box
        # (the float state found by Newton has Vdot of order -1e-30, not 0)
        fx = model.closed_loop_at(_target(target, model))
        proved_points = [(e, verify_zero(x, fx, e.state)) for e in others]
        proved_points = [(e, b) for e, b in proved_points if b is not None]
        if others and not proved_points:
            report.details["stationary_points_unverified"] = True
        if proved_points:
            e, zbox = min(proved_points,
                          key=lambda p: float(np.asarray(both(p[0].state)[0]).item()))
            d = float(np.asarray(both(e.state)[1]).item())
            report.status, report.counterexample = "counterexample", e.state
            report.route = "gradient_flow"
            report.worst_vdot, report.worst_state = max(d, best_d), e.state
            report.details["stationary_box"] = zbox
            report.method = (
                "gradient flow: Vdot = -sum_i c_i (dV/dx_i)^2 <= 0 holds identically (symbolic); "
                f"it vanishes at a {e.kind} stationary point other than the target, found by "
                "multistart Newton and proved by the Krawczyk test: exactly one state with "
                f"f = 0, hence Vdot = 0, lies within {max(zbox['radius']):.3g} of the reported "
                "state"
            )
            return report

    # 3) multistart IPOPT maximizing Vdot over the region, away from the equilibrium
    order = np.argsort(-np.where(np.isfinite(D), D, np.inf))
    k = max(1, starts // 2)
    chosen = np.concatenate([order[:k], rng.choice(len(P), size=min(k, len(P)), replace=False)])
    # admissibility constraints (e.g. outside every obstacle) kept a hair inside the boundary
    cons = cs.substitute(model.state_constraints(), model.sym.p, cs.DM(model.p_value()))
    ncons = cons.numel()
    solver = cs.nlpsol("vdot_max", "ipopt", {"x": x, "f": -vdot_num, "g": cs.vertcat(v_num, cons)},
                       _IPOPT)
    lbg = np.concatenate([[v_floor], np.full(ncons, 1e-9)])
    ubg = np.concatenate([[np.inf if level is None else level], np.full(ncons, np.inf)])
    runs = 0
    for j in chosen:
        try:
            sol = solver(x0=P[j], lbx=box.lower, ubx=box.upper, lbg=lbg, ubg=ubg)
        except RuntimeError as exc:       # evaluation errors at singular states
            log.debug("IPOPT start %s failed: %s", P[j], exc)
            continue
        runs += 1
        xs = np.clip(np.asarray(sol["x"]).ravel(), box.lower, box.upper)
        v, d = (float(np.asarray(a).item()) for a in both(xs))
        if not (np.isfinite(v) and v >= v_floor * (1 - 1e-9)):
            continue
        if not witness.within_level(xs, level):   # IPOPT may step just past the level set
            continue
        if not model.admissible(xs[None])[0]:
            continue
        if not np.isnan(d) and d > best_d:
            best_d, best_x, how = d, xs, "multistart IPOPT"
    report.details.update(ipopt_runs=runs)
    report.worst_vdot, report.worst_state = best_d, best_x
    use_cert = model.nx <= 3 if certificate is None else bool(certificate)
    # the sign of Vdot at the worst state, from its interval enclosure: floating point decides
    # nothing near zero
    sign, d_lo, d_hi = witness.vdot_sign(best_x)
    report.details["worst_vdot_enclosure"] = [d_lo, d_hi]
    route = "ipopt" if how == "multistart IPOPT" else "sampling"
    if sign in ("positive", "zero") and not witness.within_level(best_x, level):
        # a state on the level set's boundary to rounding: not surely in the analysed set
        report.status, report.route = "undecided", route
        report.method = (f"{how}: Vdot = {best_d:.6g} >= 0 at "
                         f"{np.array2string(best_x, precision=6)}, but V there is not surely "
                         f"<= the level {level!r} (its enclosure reaches above it)")
    elif sign in ("positive", "zero"):
        zero = " (exactly zero)" if sign == "zero" else ""
        _counterexample(report, both, best_x, f"{how}: Vdot = {best_d:.6g}{zero} >= 0 at this "
                        "state", witness)
        report.route = route
        report.worst_vdot = max(report.worst_vdot, best_d)
        if use_cert and sign == "zero":
            # Vdot only reaches zero: V may still decide convergence through LaSalle
            _lasalle_route(report, model, v_num, box, level, max_boxes)
    elif sign == "rounding":
        report.status, report.route = "undecided", route
        report.details["vdot_zero_state"] = best_x.tolist()
        report.method = (
            f"{how}: Vdot = {best_d:.6g} at {np.array2string(best_x, precision=6)} is zero to "
            f"rounding: its interval enclosure [{d_lo:.3g}, {d_hi:.3g}] holds 0, so neither "
            "Vdot >= 0 there nor strict decrease can be claimed (V is at best not strictly "
            "decreasing)"
        )
        if use_cert:
            _lasalle_route(report, model, v_num, box, level, max_boxes)
    else:
        report.status = "no_counterexample"
        report.route = "sampling"
        extra = "; Vdot <= 0 is exact (gradient flow)" if grad_flow else ""
        encl = (f" (its interval enclosure at that state is [{d_lo:.3g}, {d_hi:.3g}] < 0)"
                if best_d >= 0 else "")
        report.method = (
            f"dense sampling ({int(keep.sum())} states in the region) and {runs} IPOPT runs found "
            f"no Vdot >= 0 (max {best_d:.6g}{encl}){extra}; not a proof"
        )
        if use_cert:
            _certificate_route(report, model, v_num, both, box, level, xmin, target, max_boxes,
                               witness)
    if report.status == "proved" and nan:
        # a proof over K while floating point cannot evaluate Vdot at sampled states of K: the
        # enclosures and the samples disagree about the same set; claim nothing
        report.status = "undecided"
        report.method = (f"not claimed: {report.method}; but Vdot is not a number in floating "
                         f"point at {nan} sampled states of K (overflow?), so the claim is not "
                         "re-checked")
        report.claim = ""
    return report


def _check_settings(model: Model, box: Box, target, **kw) -> None:
    """Refuse settings the check cannot use, naming the key."""
    for key in ("samples", "starts", "max_boxes"):
        v = kw[key]
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise HybridnavError(f"{key}: expected a positive integer, got {v!r}")
    ex = kw["exclude"]
    if not (isinstance(ex, (int, float, np.floating)) and 0 <= ex < 1):
        raise HybridnavError(f"exclude: expected a number in [0, 1), got {ex!r}")
    level = kw["level"]
    if level is not None and not (isinstance(level, (int, float, np.floating))
                                  and not isinstance(level, bool) and np.isfinite(level)
                                  and level > 0):
        raise HybridnavError(f"level: expected a finite number > 0, got {level!r}")
    t = _target(target, model)
    if not np.all((t >= box.lower[:len(t)]) & (t <= box.upper[:len(t)])):
        raise HybridnavError(
            f"target: {t.tolist()} lies outside the region ({box.to_dict()}); a region of "
            "attraction or a Lyapunov proof is about a region holding the equilibrium")


def _sample(both, box: Box, level, n: int, rng) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n`` states, ``V`` and ``Vdot`` there: uniform in the box, and, where fewer than a tenth
    fall in ``{V <= level}``, more drawn from boxes around that set (evidence only: the
    certificate route covers the whole box)."""
    def draw(b: Box):
        p = b.sample(n, rng)
        v, d = evaluate_rows(both, p)
        return p, v.ravel(), d.ravel()

    pts, v, d = draw(box)
    if level is None:
        return pts, v, d
    for _ in range(40):
        inside = v <= level
        if inside.sum() >= n // 10:
            break
        if inside.any():
            lo, hi = pts[inside].min(axis=0), pts[inside].max(axis=0)
            span = np.maximum(hi - lo, 1e-12 * (box.upper - box.lower))
            lo, hi = lo - span, hi + span
        else:
            c = pts[int(np.nanargmin(np.where(np.isnan(v), np.inf, v)))]
            half = (box.upper - box.lower) / 2 ** (_ + 2)
            lo, hi = c - half, c + half
        sub = Box(box.names, np.maximum(lo, box.lower), np.minimum(hi, box.upper))
        p2, v2, d2 = draw(sub)
        keep = v <= level
        pts = np.vstack([pts[keep], p2])[:n] if keep.sum() < n else pts[keep][:n]
        v = np.concatenate([v[keep], v2])[:n]
        d = np.concatenate([d[keep], d2])[:n]
    return pts, v, d


def _certificate_inputs(model: Model, target):
    """The closed loop and the admissibility constraints in the state only; periodic states."""
    f = model.closed_loop_at(_target(target, model))
    g = cs.substitute(model.state_constraints(), model.sym.p, cs.DM(model.p_value()))
    return f, g


def _periodic(model: Model, box: Box) -> list[int]:
    """Angle states whose bounds span a whole turn: their faces are the same states.

    The span is compared exactly (as rationals) with ``2 * np.pi``, the float nearest a turn;
    a relative tolerance let a box 6e-9 short of a turn skip its faces, and the claimed invariant
    set then lost the states in the gap."""
    from fractions import Fraction

    angles = set(getattr(model, "angle_state_names", ()))
    turn = Fraction(2 * np.pi)
    return [i for i, n in enumerate(box.names)
            if n in angles and np.isfinite(box.lower[i]) and np.isfinite(box.upper[i])
            and Fraction(float(box.upper[i])) - Fraction(float(box.lower[i])) >= turn]


def _certificate_route(report, model, v_num, both, box, level, xmin, target, max_boxes,
                       witness=None) -> None:
    """Interval branch and bound for V > 0 and Vdot < 0; updates the report in place."""
    from hybridnav.analysis.certificate import certify

    f, g = _certificate_inputs(model, target)
    center = _equilibrium_guess(model, both, xmin, target, box)
    cert = certify(model.sym.x, f, v_num, box, level=level, constraints=g, center=center,
                   periodic=_periodic(model, box), max_boxes=max_boxes)
    report.details["certificate"] = cert.to_dict()
    if cert.status == "proved":
        report.status, report.route = "proved", "certificate"
        report.claim = cert.claim
        # (within a rounding radius r0 > 0 of x* nothing was shown)
        report.vdot_nonpositive_proved = cert.details.get("ball", {}).get("r0", 0.0) == 0.0
        report.method = f"certificate: {cert.method}; {cert.claim}"
    elif cert.status == "counterexample":
        _counterexample(report, both, cert.counterexample, cert.method, witness)
        report.route = "certificate"
    else:
        report.method += f"; the certificate route is {cert.status}: {cert.method}"


def _lasalle_route(report, model, v_num, box, level, max_boxes) -> None:
    """Branch and bound on LaSalle's conditions after a Vdot = 0 counterexample."""
    from hybridnav.analysis.certificate import certify

    target = report.details.get("target")
    if target is None:
        return
    f, g = _certificate_inputs(model, target)
    cert = certify(model.sym.x, f, v_num, box, level=level, constraints=g, lasalle=True,
                   periodic=_periodic(model, box), max_boxes=max_boxes)
    report.details["lasalle"] = cert.to_dict()
    if cert.status == "proved":
        report.details["vdot_zero_state"] = report.worst_state.tolist()
        report.status, report.route = "proved", "lasalle"
        report.claim = cert.claim           # Vdot <= 0 outside the small set {V < eps}
        report.method = (f"LaSalle: V is not strictly decreasing ({report.method}); "
                         f"{cert.method}; {cert.claim}")
        report.counterexample = None
    else:
        report.method += f"; LaSalle's route is {cert.status}: {cert.method}"


def _target_state(model: Model, target) -> np.ndarray:
    """The state at the target: its position the target's, the other states 0."""
    t = _target(target, model)
    x = np.zeros(model.nx)
    x[:len(t)] = t
    return x


def _equilibrium_guess(model, both, xmin, target, box) -> np.ndarray:
    """Where V vanishes: the minimizer of V, or the same with its position at the target when V
    is smaller there (the certificate's local ball is centred on it)."""
    snapped = np.asarray(xmin, dtype=float).copy()
    snapped[:model.target_size] = _target(target, model)
    best = np.asarray(xmin, dtype=float)
    if box.contains(snapped):
        v0 = abs(float(np.asarray(both(best)[0]).item()))
        v1 = abs(float(np.asarray(both(snapped)[0]).item()))
        if v1 <= v0:
            best = snapped
    return best


# ---------------------------------------------------------------------------------------------


def _minimize_v(model, v_of, v_num, box: Box, level, pts, v_s, ok, starts) -> np.ndarray:
    """The minimizer of V over the region: the best samples refined by IPOPT (``v_of(x)`` is
    V at a state)."""
    x = model.sym.x
    cons = cs.substitute(model.state_constraints(), model.sym.p, cs.DM(model.p_value()))
    g = cs.vertcat(v_num, cons) if level is not None else cons
    solver = cs.nlpsol("v_min", "ipopt", {"x": x, "f": v_num, "g": g}, _IPOPT)
    ncons = cons.numel()
    lbg = np.full(ncons, 1e-9)
    ubg = np.full(ncons, np.inf)
    if level is not None:
        lbg, ubg = np.concatenate([[-np.inf], lbg]), np.concatenate([[level], ubg])
    idx = np.flatnonzero(ok)
    order = idx[np.argsort(v_s[idx])][:max(1, starts // 4)]
    best = pts[order[0]] if len(order) else (box.lower + box.upper) / 2
    best_v = float(np.asarray(v_of(best)).item())
    for j in order:
        try:
            sol = solver(x0=pts[j], lbx=box.lower, ubx=box.upper, lbg=lbg, ubg=ubg)
        except RuntimeError:
            continue
        xs = np.clip(np.asarray(sol["x"]).ravel(), box.lower, box.upper)
        if not model.admissible(xs[None])[0]:
            continue
        v = float(np.asarray(v_of(xs)).item())
        if np.isfinite(v) and v < best_v:
            best, best_v = xs, v
    return np.asarray(best, dtype=float)


def _local_check(model, v_num, vdot_num, both, xmin, box: Box, level, report, witness,
                 tol: float = 1e-9):
    """The quadratic parts of V and Vdot at the minimizer of V (where sampling cannot look).

    Returns (state, method) of a counterexample a small step away, or None.
    """
    x = model.sym.x
    fn = cs.Function("local", [x], [cs.hessian(v_num, x)[0], cs.gradient(vdot_num, x),
                                    cs.hessian(vdot_num, x)[0]])
    try:
        hv, gd, hd = (np.asarray(a, dtype=float) for a in fn(xmin))
    except RuntimeError:
        return None
    if not (np.all(np.isfinite(hv)) and np.all(np.isfinite(hd)) and np.all(np.isfinite(gd))):
        return None
    hv, hd = (hv + hv.T) / 2, (hd + hd.T) / 2
    ev_v, vv = np.linalg.eigh(hv)
    ev_d, vd = np.linalg.eigh(hd)
    scale = max(float(np.max(np.abs(hv))), float(np.max(np.abs(hd))), 1e-300)
    report.details.update(local_point=xmin.tolist(), local_eig_hessian_V=ev_v.tolist(),
                          local_eig_hessian_vdot=ev_d.tolist(),
                          local_grad_vdot=gd.ravel().tolist())
    span = float(np.min(box.upper - box.lower))
    candidates = []
    if ev_v.min() < -tol * scale:
        candidates.append((vv[:, int(np.argmin(ev_v))], "V", "the Hessian of V there has the "
                           f"eigenvalue {ev_v.min():.6g} < 0"))
    gn = float(np.linalg.norm(gd))
    if gn > tol * scale:
        candidates.append((gd.ravel() / gn, "Vdot", f"Vdot has the gradient norm {gn:.6g} there, "
                           "so it is positive on one side"))
    if ev_d.max() > tol * scale:
        candidates.append((vd[:, int(np.argmax(ev_d))], "Vdot", "the Hessian of Vdot there has "
                           f"the eigenvalue {ev_d.max():.6g} > 0"))
    for direction, which, why in candidates:
        for h in span * np.array([1e-3, 1e-4, 1e-5]):
            for sign in (1.0, -1.0):
                z = xmin + sign * h * direction
                if not box.contains(z) or not model.admissible(z[None])[0]:
                    continue
                v = float(np.asarray(both(z)[0]).item())
                if level is not None and v > level:
                    continue
                lo, hi = witness.enclose(z)
                if (which == "V" and hi[0, 0] < 0) or (which == "Vdot" and lo[0, 1] > 0):
                    return z, (f"local check near the minimizer of V "
                               f"{np.array2string(xmin, precision=6)}: {why}; a step of "
                               f"{h:.3g} along it gives {which} "
                               f"{'< 0' if which == 'V' else '> 0'}")
    return None


def is_gradient_flow(model: Model, v_sym) -> bool:
    """Whether the closed loop is ``xdot_i = -c_i dV/dx_i`` symbolically, with ``c_i > 0``."""
    gains = getattr(model, "gradient_flow_gains", None)
    if gains is None:
        return False
    c = gains()
    cval = np.asarray(cs.Function("c", [model.sym.p], [c])(model.p_value())).ravel()
    if not np.all(cval > 0):
        return False
    f = model.closed_loop()
    xs = model.sym.x
    g = cs.gradient(v_sym, xs)
    return all(cs.is_equal(f[i], -c[i] * g[i], 1000) for i in range(model.nx))


def _candidate(model: Model, V, orig: Model | None = None) -> cs.SX:
    s = model.sym
    if V is None:
        return model.lyapunov_candidate()
    if isinstance(V, (cs.SX, float, int)):
        expr = cs.SX(V)
        if orig is not None and orig is not model:
            # built from the caller's model.sym; params= made a new model with its own symbols
            o = orig.sym
            expr = cs.substitute(expr, cs.vertcat(o.x, o.target, o.p),
                                 cs.vertcat(s.x, s.target, s.p))
    elif callable(V):
        try:
            nparams = len(inspect.signature(V).parameters)
        except (TypeError, ValueError):
            nparams = 1
        expr = V(s.x, s.target) if nparams >= 2 else V(s.x)
        if not isinstance(expr, cs.SX):
            raise HybridnavError(
                "V: expected the callable to return a CasADi SX expression of the state, got "
                f"{type(expr).__name__}"
            )
    else:
        raise HybridnavError(
            f"V: expected a CasADi SX expression or a callable V(x[, target]), got "
            f"{type(V).__name__}"
        )
    if expr.shape != (1, 1):
        raise HybridnavError(f"V: expected a scalar expression, got shape {expr.shape}")
    allowed = cs.symvar(cs.vertcat(s.x, s.target, s.p))
    free = [v for v in cs.symvar(expr) if not any(cs.is_equal(v, a) for a in allowed)]
    if free:
        # symbols of the same system built again (as_system traces a python-control system on
        # every call) or the user's own: taken by name when they name a state, target entry or
        # parameter
        by_name = {str(a): a for a in allowed}
        alias = getattr(model, "aliases", {})
        pairs = [(v, by_name.get(str(v), alias.get(str(v)))) for v in free]
        pairs = [(v, a) for v, a in pairs if a is not None]
        if pairs:
            expr = cs.substitute(expr, cs.vertcat(*[v for v, _ in pairs]),
                                 cs.vertcat(*[a for _, a in pairs]))
        free = [str(v) for v in cs.symvar(expr) if not any(cs.is_equal(v, a) for a in allowed)]
    if free:
        raise HybridnavError(
            f"V: depends on symbols that are not the model's state, target or parameters: "
            f"{', '.join(free)} (build V from model.sym.x)"
        )
    return expr


def _pretty(expr) -> str:
    return str(expr)


