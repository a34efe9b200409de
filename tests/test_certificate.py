"""Interval arithmetic, the certificate route, LaSalle, and the better regions of attraction."""

from __future__ import annotations

import math

import casadi as cs
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp
from scipy.linalg import solve_continuous_lyapunov

from hybridnav import HybridnavError, models
from hybridnav.analysis import check_lyapunov, find_equilibria
from hybridnav.analysis.certificate import certify
from hybridnav.analysis.interval import IntervalFunction, UnsupportedOperation
from hybridnav.analysis.region import Box
from hybridnav.analysis.roa import basin, estimate_roa, lyapunov_equation_candidate
from hybridnav.models.base import wrap_angle
from hybridnav.world import load_scenario

BOX = {"x": (0.0, 50.0), "y": (0.0, 50.0)}
_x = cs.SX.sym("x", 3)
EXPRESSIONS = [
    _x[0] * _x[1] - _x[2], 1 / (_x[0] ** 2 + 0.1), cs.sin(3 * _x[0]) * cs.cos(_x[1]),
    cs.atan2(_x[1], _x[0]), cs.sqrt(_x[0] ** 2 + _x[1] ** 2), cs.fmax(_x[0], _x[1]) * cs.fabs(_x[2]),
    cs.exp(_x[0]) * cs.log(_x[1] ** 2 + 1), _x[0] ** 3 - _x[1] ** 4, wrap_angle(3 * _x[2]),
    cs.cos(wrap_angle(_x[0] - _x[1])), cs.if_else(_x[0] > 0, _x[1], -_x[1]), _x[0] / _x[1],
    cs.tanh(_x[0] * _x[2]), cs.atan(_x[0]) + cs.fmin(_x[1], 0.5), (_x[0] - 1) ** 2 * cs.sin(_x[1]),
    cs.sqrt(_x[0]) + cs.log(_x[1]), cs.asin(_x[2] / 4), cs.fabs(_x[0]) ** 2.5 * 10.0 ** _x[1],
    cs.tanh(cs.log(_x[0] - 2)),
]
F_INTERVAL = IntervalFunction(_x, EXPRESSIONS)
F_POINT = cs.Function("f", [_x], [cs.vertcat(*EXPRESSIONS)])


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_interval_enclosures_hold_at_sampled_states_and_corners(seed):
    rng = np.random.default_rng(seed)
    n = 64
    c = rng.uniform(-4, 4, (n, 3))
    w = 10.0 ** rng.uniform(-6, 0.8, (n, 3))
    lo, hi = c - w, c + w
    out_lo, out_hi, _ = F_INTERVAL(lo, hi)
    corners = np.array(np.meshgrid(*[[0, 1]] * 3, indexing="ij")).reshape(3, -1).T
    pts = [np.clip(lo + (hi - lo) * rng.random((n, 3)), lo, hi) for _ in range(20)]
    pts += [np.where(k == 1, hi, lo) for k in corners]      # exactly the corners
    for P in pts:
        v = np.asarray(F_POINT.map(n)(P.T)).T
        ok = np.isnan(v) | ((v >= out_lo) & (v <= out_hi))
        assert ok.all(), np.argwhere(~ok)[:3]


def test_interval_keeps_exact_zeros_and_sees_through_wrapped_angles():
    rho, e = cs.SX.sym("rho"), cs.SX.sym("e")
    z = cs.vertcat(rho, e)
    F = IntervalFunction(z, [-0.5 * rho * (rho * cos_sq(e)), cs.cos(wrap_angle(e))])
    lo, hi, smooth = F(np.array([[1.0, 1.5]]), np.array([[2.0, 1.7]]))   # e around pi/2
    assert hi[0, 0] == 0.0                     # -k rho^2 cos^2 e <= 0 exactly, not 1e-300
    # across the jump of wrap(e) at pi, cos(wrap(e)) is cos(e), near -1 (not [-1, 1])
    lo, hi, smooth = F(np.array([[1.0, 3.0]]), np.array([[2.0, 3.3]]))
    assert hi[0, 1] < -0.98 and lo[0, 1] >= -1 - 1e-12
    assert smooth[0, 1]                        # wrap(e) jumps, cos(wrap(e)) = cos(e) does not
    F2 = IntervalFunction(z, [wrap_angle(e)])
    assert not F2(np.array([[1.0, 3.0]]), np.array([[2.0, 3.3]]))[2][0, 0]   # the jump itself
    assert F2(np.array([[1.0, 1.0]]), np.array([[2.0, 2.0]]))[2][0, 0]
    with pytest.raises(UnsupportedOperation, match="erf"):
        IntervalFunction(z, [cs.erf(rho)])


def cos_sq(e):
    return cs.cos(e) ** 2


def _point_mass(V, target=(45.0, 5.0), **kw):
    return check_lyapunov(models.get("point_mass"), V, target=target, region=BOX, **kw)


def test_a_non_quadratic_candidate_is_proved_by_the_certificate():
    """V = dx^4 + dy^4 + dx^2 + dy^2: Vdot = -0.1 (4 dx^4 + 2 dx^2 + 4 dy^4 + 2 dy^2) < 0."""
    rep = _point_mass(lambda x, t: (x[0] - t[0]) ** 4 + (x[1] - t[1]) ** 4 + (x[0] - t[0]) ** 2
                      + (x[1] - t[1]) ** 2)
    assert rep.status == "proved" and rep.route == "certificate"
    assert "V > 0 and Vdot < 0 on K = {x in [0, 50] x y in [0, 50]}" in rep.claim
    assert "positively invariant" in rep.claim            # the box's faces: the flow points in
    cert = rep.details["certificate"]
    assert cert["undecided"] == 0 and cert["details"]["ball"]["r0"] == 0.0
    # without the quadratic part the Hessians vanish at x*: no local argument, so no proof
    quartic = _point_mass(lambda x, t: (x[0] - t[0]) ** 4 + (x[1] - t[1]) ** 4)
    assert quartic.status == "no_counterexample" and "certificate route is undecided" in \
        quartic.method


def test_the_needle_bump_near_a_corner_is_found():
    """Amplitude 50, width 0.05 at (1, 49): 1e5 samples over the 50 x 50 box hit it with
    probability about 0.3; the branch and bound finds it."""
    cx, cy, w = 1.0, 49.0, 0.05

    def V(x, t):
        return 0.5 * ((x[0] - t[0]) ** 2 + (x[1] - t[1]) ** 2) + 50 * cs.exp(
            -((x[0] - cx) ** 2 + (x[1] - cy) ** 2) / w**2)

    rep = _point_mass(V)
    assert rep.status == "counterexample"
    x, y = rep.counterexample
    # Vdot by hand: grad V . f with f = 0.1 (target - x)
    bump = 50 * math.exp(-((x - cx) ** 2 + (y - cy) ** 2) / w**2)
    gx = (x - 45) - 2 * (x - cx) / w**2 * bump
    gy = (y - 5) - 2 * (y - cy) / w**2 * bump
    vdot = gx * 0.1 * (45 - x) + gy * 0.1 * (5 - y)
    assert vdot > 0 and vdot == pytest.approx(rep.details["counterexample_vdot"], rel=1e-9)
    assert math.hypot(x - cx, y - cy) < 4 * w


def test_faces_where_the_flow_leaves_are_reported_not_claimed():
    """Target outside the box: V > 0 > Vdot holds on the box, but the box is not invariant."""
    m = models.get("point_mass")
    s = m.sym
    t = np.array([60.0, 5.0])
    V = 0.5 * ((s.x[0] - t[0]) ** 2 + (s.x[1] - t[1]) ** 2)
    f = cs.substitute(m.closed_loop(), cs.vertcat(s.target, s.p), cs.DM(np.r_[t, m.p_value()]))
    cert = certify(s.x, f, V, Box(("x", "y"), np.zeros(2), np.full(2, 50.0)))
    assert cert.status == "proved" and cert.invariant is False
    assert "not shown" in cert.claim
    fx, _ = cert.details["face_counterexample"]
    assert fx == 50.0                                  # the face x = 50, where xdot > 0


def test_lasalle_proves_the_unicycle_and_refuses_a_conservative_system():
    m = models.get("unicycle")
    z, zdot, names = m.polar_error_dynamics()
    zdot = cs.substitute(zdot, m.sym.p, cs.DM(m.p_value()))
    box = Box(names, np.array([0.0, -math.pi]), np.array([5.0, math.pi]))
    cert = certify(z, zdot, 0.5 * z[0] ** 2, box, lasalle=True)
    assert cert.status == "proved" and cert.invariant
    assert cert.details["counts"]["lasalle_lie"] > 0      # e = +-90 deg needed Lie derivatives
    assert "LaSalle" in cert.claim and "{V < 1.25e-05}" in cert.claim
    # V = 1/2 rho^2 is not strictly decreasing: the strict route does not claim it
    assert certify(z, zdot, 0.5 * z[0] ** 2, box, center=np.zeros(2),
                   max_boxes=20_000).status != "proved"
    # simulate: every start converges (solve_ivp on the polar dynamics)
    fz = cs.Function("f", [z], [zdot])
    for z0 in ([5.0, math.pi / 2], [3.0, -math.pi / 2], [1.0, 3.0]):
        sol = solve_ivp(lambda t, y: np.asarray(fz(y)).ravel(), (0, 60), z0, rtol=1e-9)
        assert sol.y[0, -1] < 1e-3 * z0[0]
    # a conservative oscillator: Vdot = 0 everywhere, every circle invariant: no claim
    q = cs.SX.sym("q", 2)
    osc = certify(q, cs.vertcat(q[1], -q[0]), q[0] ** 2 + q[1] ** 2,
                  Box(("a", "b"), np.full(2, -1.0), np.full(2, 1.0)), lasalle=True,
                  max_boxes=20_000)
    assert osc.status == "undecided"
    # Vdot > 0 somewhere (k_rho < 0 pushes away): a counterexample, not a claim
    bad = cs.substitute(zdot, z, z)
    bad = cs.vertcat(0.5 * z[0] * cs.cos(z[1]) ** 2, bad[1])
    neg = certify(z, bad, 0.5 * z[0] ** 2, box, lasalle=True)
    assert neg.status == "counterexample" and neg.counterexample[0] > 0


def test_check_lyapunov_tries_lasalle_after_a_zero_vdot_counterexample():
    rep = check_lyapunov(models.get("unicycle"), target=(0, 0), region={
        "x": (-5, 5), "y": (-5, 5), "theta": (-math.pi, math.pi)}, max_boxes=5_000)
    assert rep.status == "undecided"            # Cartesian: LaSalle undecided, Vdot = 0 to rounding
    assert "LaSalle's route is undecided" in rep.method
    assert "lasalle" in rep.details


def test_lbcs_is_proved_on_its_level_below_the_trap_and_the_level_is_not_capped_by_the_box():
    s = load_scenario("aco-local-minimum")
    lb = models.LbCS.from_scenario(s)
    target = s.robots[0].goal
    eqs = find_equilibria(lb, target=target, region=BOX)
    trap = min(e.V for e in eqs if not e.is_target)
    assert trap == pytest.approx(347.68, abs=0.01)
    est = estimate_roa(lb, target=target, region=BOX, confirm=100)
    assert est.status == "proved" and est.details["route"] == "certificate"
    assert 347.0 < est.level < trap and est.bounded_by == "equilibrium"
    assert "V <= 347.33" in est.details["claim"] and "positively invariant" in est.details["claim"]
    assert est.details["grown"] >= 1                      # the workspace box alone caps at 13.55
    assert est.confirmed


def test_lyapunov_equation_candidate_matches_scipy_and_is_proved():
    pm = models.get("point_mass", alpha1=0.1, alpha2=0.3)
    Q = np.array([[2.0, 0.5], [0.5, 1.0]])
    V, P = lyapunov_equation_candidate(pm, (45, 5), Q=Q)
    A = np.diag([-0.1, -0.3])
    np.testing.assert_allclose(P, solve_continuous_lyapunov(A.T, -Q), rtol=1e-12)
    rep = check_lyapunov(pm, V, target=(45, 5), region=BOX)
    assert rep.status == "proved"
    np.testing.assert_allclose(rep.details["hessian_vdot"], -2 * Q, atol=1e-12)
    with pytest.raises(HybridnavError, match="not Hurwitz"):
        lyapunov_equation_candidate(pm, (45, 5), params={"alpha1": -0.1})
    with pytest.raises(HybridnavError, match="Q: expected a symmetric positive definite"):
        lyapunov_equation_candidate(pm, (45, 5), Q=-np.eye(2))


def test_basin_agrees_with_solve_ivp_in_the_trap():
    s = load_scenario("aco-local-minimum")
    lb = models.LbCS.from_scenario(s)
    target = np.asarray(s.robots[0].goal)
    xs, ys, conv = basin(lb, target=target, region=BOX, n=21)
    assert 0.5 < conv.mean() < 0.95                # the cup traps the starts inside it
    _, _, sim = basin(lb, target=target, region=BOX, n=21, method="simulated")
    assert 0.5 < sim.mean() < 0.95                 # RK4 at dt = 0.1: close, not the same
    rhs = lb.numeric_closed_loop()
    r = 1e-3 * math.hypot(50, 50)
    rng = np.random.default_rng(3)
    checked = 0
    for iy, ix in zip(rng.integers(0, 21, 40), rng.integers(0, 21, 40)):
        z0 = np.array([xs[ix], ys[iy]])
        if not lb.admissible(z0[None])[0]:
            continue
        sol = solve_ivp(lambda t, z: rhs(z, target), (0, 2000.0), z0, rtol=1e-8, atol=1e-10,
                        method="LSODA")
        assert (np.hypot(*(sol.y[:, -1] - target)) <= r) == conv[iy, ix], z0
        checked += 1
    assert checked >= 25


# ---- what a review found (each made the certificate over-claim or an enclosure wrong) ----------

_y = cs.SX.sym("y", 1)
_LINE = Box(("y",), np.array([-1.0]), np.array([1.0]))


@pytest.mark.parametrize("f, V, box", [
    (-_y * (1 + cs.sqrt(_y + 0.5)), _y**2, _LINE),              # f is NaN below y = -0.5
    (-_y * (2 + cs.tanh(cs.log(_y - 2))), _y**2, _LINE),        # f is NaN everywhere
    (_y, _y**2 * (2 + cs.tanh(cs.log(_y + 0.5))), Box(("y",), np.array([-1.0]),
                                                     np.array([-0.6]))),   # V is NaN there
])
def test_nothing_is_proved_where_the_expressions_are_undefined(f, V, box):
    center = np.zeros(1) if box.contains(np.zeros(1)) else None   # (a centre must be in the box)
    assert certify(_y, f, V, box, center=center, max_boxes=5_000).status != "proved"


def test_enclosures_of_powers_huge_sines_infinities_and_underflows():
    from decimal import Decimal, getcontext

    getcontext().prec = 50
    x0 = 93.4050111604654
    F = IntervalFunction(_y, [_y**1.5, cs.sin(_y), cs.cosh(1 / _y)])
    lo, hi, _ = F(np.array([[x0]]), np.array([[x0]]))
    exact = Decimal(x0) * Decimal(x0).sqrt()
    assert Decimal(lo[0, 0]) <= exact <= Decimal(hi[0, 0])
    a, b = 1288408130550494.75, 1288408130550496.5       # a peak of sin lies in between
    lo, hi, _ = F(np.array([[a]]), np.array([[b]]))
    assert hi[0, 1] >= 1.0
    lo, hi, _ = F(np.array([[1e-170]]), np.array([[2e-170]]))
    assert lo[0, 2] > 1 and hi[0, 2] == np.inf               # no NaN from inf - inf
    q = cs.SX.sym("q", 2)
    lo, hi, _ = IntervalFunction(q, [q[0] / q[1]])(np.array([[2e-120, 1e300]]),
                                                   np.array([[2e-120, 1e300]]))
    assert lo[0, 0] <= 0 < hi[0, 0]                          # 2e-420 underflows to 0


def test_invariance_is_shown_or_nothing_is_claimed():
    q = cs.SX.sym("q", 2)
    square = Box(("a", "b"), np.full(2, -1.0), np.full(2, 1.0))
    # the flow -x runs into the obstacle at (0.5, 0) from (1, 0): no invariance, so no proof
    into = certify(q, -q, cs.sumsqr(q), square, constraints=(q[0] - 0.5) ** 2 + q[1] ** 2 - 0.01,
                   center=np.zeros(2), max_boxes=20_000)
    assert into.status != "proved" and into.details["counts"]["obstacle_boundary_split"] > 0
    # LaSalle without invariance (x(t) = 1 - t leaves [0.5, 1.5]): not proved
    leave = certify(_y, 0 * _y - 1, _y**2, Box(("y",), np.array([0.5]), np.array([1.5])),
                    lasalle=True)
    assert leave.status == "undecided" and leave.invariant is False
    # a side of zero width is a face on both sides: ydot = -0.5 leaves the slice y = 0.5
    flat = certify(q, -q, q[0] ** 2, Box(("a", "b"), np.array([-1.0, 0.5]), np.array([1.0, 0.5])),
                   lasalle=True)
    assert flat.invariant is False and flat.status != "proved"


def test_a_rounding_radius_is_stated_in_the_claim():
    """Vdot = -2 y (y - 1e-4) > 0 on (0, 1e-4): within r0 of x* = 0 nothing is claimed."""
    cert = certify(_y, -(_y - 1e-4), _y**2, _LINE, center=np.zeros(1))
    if cert.status == "proved":
        r0 = cert.details["ball"]["r0"]
        assert r0 >= 1e-4 and f"except within r0 = {r0:.3g} of x*" in cert.claim


def _exact_inside(state, level, v):
    """Whether ``v`` (rational coefficients) at the reported float state is at most the level,
    in exact rational arithmetic."""
    from fractions import Fraction

    return v(*(Fraction(float(c)) for c in state)) <= Fraction(level)


def test_a_counterexample_state_lies_in_the_level_set_exactly_certificate_route():
    """A review found the certificate route reporting (1, 0), 1.85e-17 outside {V <= 1/3}
    (double(1/3) is below a third), where the jump to an unstable branch sits: on the set
    itself Vdot < 0, so there is no counterexample."""
    import casadi as cs

    from hybridnav.analysis import check_lyapunov

    x = cs.SX.sym("x", 2)
    rhs = cs.vertcat(cs.if_else(x[0] >= 1, x[0], -x[0]), -x[1])
    rep = check_lyapunov((x, rhs), (x[0] ** 2 + x[1] ** 2) / 3, equilibrium=[0, 0],
                         region={"x_0": (-2, 2), "x_1": (-2, 2)}, level=1 / 3)
    assert rep.status != "counterexample", rep.counterexample


def test_a_counterexample_state_lies_in_the_level_set_exactly_quadratic_route():
    """The quadratic route reported Vdot's maximizer (1/2, 0), 4.6e-18 outside {V <= 1/12};
    the violation is real (Vdot > 0 inside the set), and the state reported must be inside."""
    import casadi as cs

    from hybridnav.analysis import check_lyapunov

    x = cs.SX.sym("x", 2)
    rhs = cs.vertcat(1 - x[0], -x[1])
    rep = check_lyapunov((x, rhs), (x[0] ** 2 + x[1] ** 2) / 3, equilibrium=[1, 0],
                         region={"x_0": (-2, 2), "x_1": (-2, 2)}, level=1 / 12)
    assert rep.status == "counterexample"
    assert _exact_inside(rep.counterexample, 1 / 12, lambda a, b: (a * a + b * b) / 3)


def test_an_angle_box_short_of_a_turn_keeps_its_faces():
    """A theta box 6e-9 short of a whole turn is not a whole turn: its faces are checked, so
    the proof does not claim K invariant (an independent 60-digit integration leaves the box
    through the gap). A review found the former relative tolerance (1e-9) skipped them."""
    import casadi as cs

    from hybridnav.analysis import as_system, check_lyapunov

    th, om = cs.SX.sym("theta"), cs.SX.sym("omega")
    sysm = as_system((cs.vertcat(th, om), cs.vertcat(om, -cs.sin(th) - 0.5 * om)),
                     states=["theta", "omega"], angles=["theta"])
    V = 1 - cs.cos(th) + om**2 / 2 + 0.2 * cs.sin(th) * om
    lo, hi = 0.5 + 3e-9, 0.5 + 2 * np.pi - 3e-9
    rep = check_lyapunov(sysm, V, equilibrium=[2 * np.pi, 0],
                         region={"theta": (lo, hi), "omega": (-3, 3)}, level=1.5)
    assert "K is positively invariant" not in rep.claim
    assert rep.status != "proved" or "invariance of K was not shown" in rep.claim
    # a whole turn as floats write it keeps the face identification
    from hybridnav.analysis.certificate import Box
    from hybridnav.analysis.lyapunov import _periodic

    box = Box(["theta", "omega"], np.array([-np.pi, -3.0]), np.array([np.pi, 3.0]))
    assert _periodic(sysm, box) == [0]
    box = Box(["theta", "omega"], np.array([lo, -3.0]), np.array([hi, 3.0]))
    assert _periodic(sysm, box) == []
