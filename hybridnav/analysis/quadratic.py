"""The exact route of :func:`~hybridnav.analysis.check_lyapunov`: V and Vdot quadratic forms with
definite constant Hessians (beyond a tolerance; ``undecided`` where rounding would decide)."""

from __future__ import annotations

import logging

import casadi as cs
import numpy as np

from hybridnav.analysis.region import Box
from hybridnav.analysis.verdict import LyapunovReport, _counterexample

__all__: list[str] = []

log = logging.getLogger(__name__)


def _quadratic_argument(model, v_num, vdot_num, box: Box, level, report: LyapunovReport,
                        tol: float = 1e-9) -> bool:
    """The exact route: V, Vdot quadratic forms with definite constant Hessians.

    Definiteness needs every eigenvalue beyond ``tol`` times the largest Hessian entry; an
    eigenvalue within that band of zero makes the status ``undecided`` (rounding would decide).
    """
    x = model.sym.x
    if not (cs.is_quadratic(v_num, x) and cs.is_quadratic(vdot_num, x)):
        return False
    z = np.zeros(model.nx)
    fn = cs.Function("quad", [x], [v_num, cs.gradient(v_num, x), cs.hessian(v_num, x)[0],
                                  vdot_num, cs.gradient(vdot_num, x), cs.hessian(vdot_num, x)[0]])
    _, gv0, hv, _, _, hd = (np.asarray(a, dtype=float) for a in fn(z))
    hv, hd = (hv + hv.T) / 2, (hd + hd.T) / 2
    ev_v, vec_v = np.linalg.eigh(hv)
    ev_d = np.linalg.eigvalsh(hd)
    scale = max(1.0, float(np.max(np.abs(hv))), float(np.max(np.abs(hd))))
    band = tol * scale
    report.details.update(hessian_V=hv.tolist(), hessian_vdot=hd.tolist(),
                          eig_hessian_V=ev_v.tolist(), eig_hessian_vdot=ev_d.tolist(),
                          eigenvalue_tolerance=band)
    if np.any(ev_v < -band):
        # V is an indefinite quadratic: V < 0 along that eigenvector, away from its centre
        try:
            xs = np.linalg.lstsq(hv, -gv0.ravel(), rcond=None)[0]
        except np.linalg.LinAlgError:
            return False
        state = _inside(xs, vec_v[:, int(np.argmin(ev_v))], box, level, fn)
        if state is None or float(np.asarray(fn(state)[0]).item()) >= 0:
            return False
        report.route = "quadratic"
        _counterexample(report, _both(fn), state,
                        f"exact: V is a quadratic form whose Hessian has the eigenvalue "
                        f"{ev_v.min():.6g} < 0; along its eigenvector V < 0")
        return True
    if not np.all(ev_v > band):
        return False                      # V only semidefinite: sample instead
    xs = np.linalg.solve(hv, -gv0.ravel())
    v0, _, _, d0, gd0, _ = (np.asarray(a, dtype=float) for a in fn(xs))
    if max(abs(v0.item()), abs(d0.item()), float(np.max(np.abs(gd0)))) > 1e-9 * scale:
        return False                      # not both centred on the same point
    report.details["equilibrium"] = xs.tolist()
    if np.all(ev_d < -band):
        report.status, report.route = "proved", "quadratic"
        report.claim = ("V > 0 and Vdot < 0 for every state other than x* (quadratic forms: the "
                        "argument is global)")
        report.vdot_nonpositive_proved = True
        report.worst_vdot, report.worst_state = 0.0, xs
        report.method = (
            "exact: V and Vdot are quadratic forms about x* = "
            f"{np.array2string(xs, precision=6)} with constant Hessians; eig(H_V) = "
            f"{np.array2string(ev_v, precision=6)} > 0 and eig(H_Vdot) = "
            f"{np.array2string(ev_d, precision=6)} < 0 (beyond the tolerance {band:.3g}), so "
            "V > 0 and Vdot < 0 for every x != x*"
        )
        return True
    if np.all(ev_d <= band):
        # the largest eigenvalue of H_Vdot is zero to rounding: neither claim can be made
        report.status, report.route = "undecided", "quadratic"
        report.worst_vdot, report.worst_state = 0.0, xs
        report.method = (
            f"exact route undecided: V and Vdot are quadratic forms about x*, V is positive "
            f"definite, but the largest eigenvalue of H_Vdot is {ev_d.max():.3g}, within the "
            f"tolerance {band:.3g} of zero: whether Vdot < 0 everywhere is decided by rounding "
            "(check the system with exact arithmetic)"
        )
        return True
    # an eigenvector with a positive eigenvalue is an exact counterexample direction
    w, vecs = np.linalg.eigh(hd)
    direction = vecs[:, int(np.argmax(w))]
    state = _inside(xs, direction, box, level, fn)
    if state is None:
        return False
    d = float(np.asarray(fn(state)[3]).item())
    if not d > 0:
        return False
    report.route = "quadratic"
    _counterexample(report, _both(fn), state,
                    "exact: Vdot is a quadratic form about x* whose Hessian has the eigenvalue "
                    f"{w.max():.6g} > 0; along its eigenvector Vdot = {d:.6g} > 0")
    return True


def _both(fn: cs.Function):
    """``x -> (V, Vdot)`` from the quadratic route's function."""
    def both(x):
        out = fn(x)
        return out[0], out[3]
    return both


def _inside(xs, direction, box: Box, level, fn) -> np.ndarray | None:
    """A point x* + t v inside the box (and level set), as far out as allowed, t != 0."""
    for sign in (1.0, -1.0):
        t = _max_step(xs, sign * direction, box)
        for _ in range(60):
            if t <= 0:
                break
            z = xs + sign * t * direction
            if level is None or float(np.asarray(fn(z)[0]).item()) <= level:
                return z
            t /= 2
    return None


def _max_step(x, d, box: Box) -> float:
    if not box.contains(x):
        return 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        hi = np.where(d > 0, (box.upper - x) / d, np.where(d < 0, (box.lower - x) / d, np.inf))
    return float(np.min(hi))
