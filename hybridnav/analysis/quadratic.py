"""The exact route of :func:`~hybridnav.analysis.check_lyapunov`: V and Vdot quadratic forms.

When ``V`` and ``Vdot`` are quadratic in the state (``casadi.is_quadratic``), Taylor's formula at a
point ``x*`` is exact: ``V(x) = V(x*) + grad V(x*)' s + s' H_V s / 2`` with ``s = x - x*``, and
likewise for ``Vdot``. The route proves ``V > 0 > Vdot`` for every ``x != x*`` when, by interval
arithmetic (no tolerance):

* ``V``, ``grad V``, ``Vdot`` and ``grad Vdot`` are exactly zero at ``x*`` (their enclosures at the
  point are ``[0, 0]``), and
* every matrix in the enclosure of ``H_V`` is positive definite and every one in that of
  ``H_Vdot`` negative definite (a lower bound on the smallest eigenvalue from the midpoint's
  eigenvalues and the radius' norm, :func:`~hybridnav.analysis.certificate._min_eig`).

Off-centre candidates are caught exactly as well: ``V`` negative at its own minimizer, or ``Vdot``
positive at its own maximizer, is a counterexample when the enclosure there shows the sign (a
candidate centred ``7e-4`` away from the target on a slow point mass has ``Vdot = +1.2e-13`` at
the midpoint, which no absolute tolerance may round away). A ``Vdot`` Hessian whose largest
eigenvalue cannot be told from zero leaves the status ``undecided``.
"""

from __future__ import annotations

import logging

import casadi as cs
import numpy as np

from hybridnav.analysis.interval import (
    IntervalFunction,
    UnsupportedOperation,
    is_polynomial,
)
from hybridnav.analysis.region import Box
from hybridnav.analysis.verdict import LyapunovReport, _counterexample
from hybridnav.analysis.witness import Witness

__all__: list[str] = []

log = logging.getLogger(__name__)


def _quadratic_argument(model, v_num, vdot_num, box: Box, level, report: LyapunovReport,
                        center=None) -> bool:
    """The exact route (see the module docstring); True when it decided the report.

    ``center`` is a guess of the equilibrium (tried before ``V``'s own minimizer).
    """
    from hybridnav.analysis.certificate import _max_eig, _min_eig

    x = model.sym.x
    nx = model.nx
    # polynomial by the expression graph first: is_quadratic trusts automatic differentiation,
    # which sign, fabs or fmin fool (-x^2 + 3|x| has the constant AD Hessian -2)
    if not (is_polynomial(x, [v_num, vdot_num]) and cs.is_quadratic(v_num, x)
            and cs.is_quadratic(vdot_num, x)):
        return False
    gv, hv_e = cs.gradient(v_num, x), cs.hessian(v_num, x)[0]
    gd, hd_e = cs.gradient(vdot_num, x), cs.hessian(vdot_num, x)[0]
    fn = cs.Function("quad", [x], [v_num, gv, hv_e, vdot_num, gd, hd_e])
    try:
        F = IntervalFunction(x, [v_num, gv, vdot_num, gd, hv_e, hd_e])
    except UnsupportedOperation:
        return False
    witness = Witness(x, v_num, vdot_num)
    z = np.zeros(nx)
    _, gv0, hv, _, gd0, hd = (np.asarray(a, dtype=float) for a in fn(z))
    hv, hd = (hv + hv.T) / 2, (hd + hd.T) / 2
    ev_v, vec_v = np.linalg.eigh(hv)
    ev_d, vec_d = np.linalg.eigh(hd)
    zl, zh, _ = F(z[None], z[None])
    base = 2 + 2 * nx
    m_v = _min_eig(zl[0, base:base + nx * nx], zh[0, base:base + nx * nx], nx)
    M_d = _max_eig(zl[0, base + nx * nx:], zh[0, base + nx * nx:], nx)
    report.details.update(hessian_V=hv.tolist(), hessian_vdot=hd.tolist(),
                          eig_hessian_V=ev_v.tolist(), eig_hessian_vdot=ev_d.tolist(),
                          eig_bounds={"min_eig_H_V_at_least": m_v, "max_eig_H_Vdot_at_most": M_d})
    if ev_v.min() < 0:
        # an indefinite quadratic: V < 0 along that eigenvector, away from its centre
        xs = np.linalg.lstsq(hv, -gv0.ravel(), rcond=None)[0]
        state = _inside(xs, vec_v[:, int(np.argmin(ev_v))], box, level, witness)
        if state is None or not witness.v_negative(state)[0]:
            return False
        report.route = "quadratic"
        _counterexample(report, _both(fn), state,
                        f"exact: V is a quadratic form whose Hessian has the eigenvalue "
                        f"{ev_v.min():.6g} < 0; along its eigenvector V < 0", witness)
        return True
    if not m_v > 0:
        return False                      # V not shown positive definite: sample instead
    xs = np.linalg.solve(hv, -gv0.ravel())
    tries = [np.asarray(center, dtype=float)] if center is not None else []
    tries.append(xs)
    for c in tries:
        cl, ch, _ = F(c[None], c[None])
        if np.all(cl[0, :base] == 0) and np.all(ch[0, :base] == 0):
            return _centred(report, fn, witness, c, ev_v, ev_d, vec_d, m_v, M_d, box, level)
    # not centred on one point: V's minimum below zero, or Vdot's maximum above it, is a
    # counterexample where the enclosure shows it (inside the region)
    if box.contains(xs) and witness.v_negative(xs)[0]:
        report.route = "quadratic"
        _counterexample(report, _both(fn), xs, "exact: V is a quadratic form whose minimum, at "
                        "this state, is negative", witness)
        return True
    if ev_d.max() < 0:
        xd = np.linalg.solve(hd, -gd0.ravel())
        if box.contains(xd) and witness.within_level(xd, level):
            if witness.vdot_sign(xd)[0] == "positive":
                report.route = "quadratic"
                _counterexample(report, _both(fn), xd, "exact: Vdot is a quadratic form whose "
                                "maximum, at this state, is positive (V and Vdot are not centred "
                                "on the same point)", witness)
                return True
    return False


def _centred(report, fn, witness, c, ev_v, ev_d, vec_d, m_v, M_d, box, level) -> bool:
    report.details["equilibrium"] = c.tolist()
    if M_d < 0:
        report.status, report.route = "proved", "quadratic"
        report.claim = ("V > 0 and Vdot < 0 for every state other than x* = "
                        f"{np.array2string(c, precision=6)} (quadratic forms: the argument is "
                        "global)")
        report.vdot_nonpositive_proved = True
        report.worst_vdot, report.worst_state = 0.0, c
        report.method = (
            "exact: V and Vdot are quadratic forms; at x* = "
            f"{np.array2string(c, precision=6)} V, grad V, Vdot and grad Vdot are exactly zero "
            "(interval enclosures [0, 0]), and by interval bounds on the constant Hessians every "
            f"eigenvalue of H_V is >= {m_v:.6g} > 0 and every eigenvalue of H_Vdot <= {M_d:.6g} "
            f"< 0 (eig(H_V) = {np.array2string(ev_v, precision=6)}, eig(H_Vdot) = "
            f"{np.array2string(ev_d, precision=6)}), so by Taylor's formula, exact for quadratics, "
            "V > 0 and Vdot < 0 for every x != x*; no tolerance was used"
        )
        return True
    # along the eigenvector of the largest eigenvalue Vdot = lambda t^2 / 2: a counterexample
    # where the enclosure there shows Vdot > 0, or Vdot = 0 exactly (a semidefinite H_Vdot)
    direction = vec_d[:, int(np.argmax(ev_d))]
    state = _inside(c, direction, box, level, witness)
    sign = witness.vdot_sign(state)[0] if state is not None else ""
    if sign in ("positive", "zero"):
        report.route = "quadratic"
        what = ("Vdot > 0" if sign == "positive"
                else "Vdot = 0 exactly (H_Vdot is only semidefinite)")
        _counterexample(report, _both(fn), state,
                        "exact: Vdot is a quadratic form about x* whose Hessian has the "
                        f"eigenvalue {ev_d.max():.6g}; along its eigenvector {what}", witness)
        return True
    # the largest eigenvalue of H_Vdot cannot be told from zero: neither claim can be made
    report.status, report.route = "undecided", "quadratic"
    report.worst_vdot, report.worst_state = 0.0, c
    report.method = (
        f"exact route undecided: V and Vdot are quadratic forms about x*, V is positive definite, "
        f"but the largest eigenvalue of H_Vdot is {ev_d.max():.3g} and its interval bound "
        f"{M_d:.3g} is not below zero: whether Vdot < 0 everywhere is decided by rounding (check "
        "the system with exact arithmetic)"
    )
    return True


def _both(fn: cs.Function):
    """``x -> (V, Vdot)`` from the quadratic route's function."""
    def both(x):
        out = fn(x)
        return out[0], out[3]
    return both


def _inside(xs, direction, box: Box, level, witness: Witness) -> np.ndarray | None:
    """A point x* + t v inside the box (and surely inside the level set), as far out as
    allowed, t != 0."""
    for sign in (1.0, -1.0):
        t = _max_step(xs, sign * direction, box)
        for _ in range(60):
            if t <= 0:
                break
            z = xs + sign * t * direction
            if witness.within_level(z, level):
                return z
            t /= 2
    return None


def _max_step(x, d, box: Box) -> float:
    if not box.contains(x):
        return 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        hi = np.where(d > 0, (box.upper - x) / d, np.where(d < 0, (box.lower - x) / d, np.inf))
    return float(np.min(hi))
