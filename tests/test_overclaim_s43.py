"""Adversarial review s43: over-claims of hybridnav.analysis on inputs the suite lacked, each
checked against an exact computation (fractions.Fraction on the float constants the CasADi
expression holds, so the field is the one the analysis saw). Each was a strict xfail at 1e974a7
and is a plain test since the fix.

find_equilibria accepted a Newton end point ``z`` whose ``z +- 1e-9 * extent`` box the interval
tests could not clear of a zero, when the field was continuous there: a field whose components
never vanish but come within ``~ |J| r + r^2`` of 0 (``r`` the box's half-width: 4e-9 in (-2, 2),
2e-7 in (-100, 100)) was not refused, nor a jump across 0 (``if_else``, ``floor``). The box is now
bisected until its parts exclude a zero, and a part where the field may jump needs a point where
the jumping components are 0 to rounding. A Newton end where ``1 - cos x`` rounds to 0 far from
the true (double) zero was classified from its own Jacobian; the spread now covers where the zero
may be. estimate_roa's final certificate loop crept down a hair per try and gave up as
"counterexample" at level 0; its steps now grow.
"""

from __future__ import annotations

from fractions import Fraction

import casadi as cs
import numpy as np
import pytest

from equilibria_cases import X as _X
from equilibria_cases import eqs as _eqs
from equilibria_cases import roa as _roa
from equilibria_cases import states as _states

R100 = {"x_0": (-100, 100), "x_1": (-100, 100)}


def test_a_field_bounded_away_from_zero_has_no_equilibrium():
    # f1 = 1e14 (-(x^2 - 2x + 1) - 1e-14) = -1e14 ((x - 1)^2 + d), d = the float 1e-14 > 0:
    # f1 <= -1e14 d ~ -1 for every real x, exactly. 1e974a7 reports (0.99999999339, 0)
    # "degenerate", where f1 = -1.0.
    X, Y = _X[0], _X[1]
    d = 1e-14
    assert Fraction(1e14) * Fraction(d) > Fraction(99, 100)        # the bound |f1| >= 0.99
    eqs = _eqs(cs.vertcat(1e14 * (-(X ** 2 - 2 * X + 1) - d), -Y), region=R100)
    for s in _states(eqs):
        x0 = Fraction(s[0])
        f1 = Fraction(1e14) * (-(x0 * x0 - 2 * x0 + 1) - Fraction(d))
        assert f1 == 0, (s, float(f1))
    assert eqs == [], _states(eqs)


def test_estimate_roa_names_no_decreasing_state_as_the_equilibrium_bound():
    # f1 = -(x^3 - 2x^2 + c x) with c = float(1 + 1e-13) > 1, i.e. -x ((x - 1)^2 + (c - 1)):
    # the only zero is the origin, and V = x^2 + y^2 has Vdot = 2 x f1 - 2 y^2 < 0 off it.
    # 1e974a7: find_equilibria adds (0.9999999494, 0) ("degenerate", f1 = -1.02e-13), and
    # estimate_roa returns level 0.999, bounded_by "equilibrium", counterexample that point,
    # where Vdot = -2.05e-13 < 0 exactly.
    X, Y = _X[0], _X[1]
    c = 1 + 1e-13
    assert Fraction(c) > 1
    f = cs.vertcat(-(X ** 3 - 2 * X ** 2 + c * X), -Y)
    r = _roa((_X, f), X ** 2 + Y ** 2, equilibrium=[0, 0], region=R100)
    if r.counterexample is not None:
        x0, y0 = (Fraction(float(v)) for v in np.asarray(r.counterexample, dtype=float))
        f1 = -(x0 ** 3 - 2 * x0 ** 2 + Fraction(c) * x0)
        vdot = 2 * x0 * f1 - 2 * y0 * y0
        assert vdot > 0 or (f1 == 0 and y0 == 0), (r.bounded_by, r.counterexample, float(vdot))
    assert r.bounded_by != "equilibrium", (r.level, r.counterexample)


# ---------------------------------------------------------------- jumps over zero (if_else, floor)

RB = {"x_0": (-1e4, 1e4), "x_1": (-1e4, 1e4)}


def _exact_jump_field(s, c, floor=False):
    """f1 = 1e8 * (x + c) for x >= 0 and 1e8 * (x - c) for -1 <= x < 0, in exact arithmetic."""
    x0 = Fraction(s[0])
    if floor:       # x + c (2 floor(x) + 1): floor(x) = 0 on [0, 1), -1 on [-1, 0)
        k = 0 if 0 <= x0 < 1 else -1
        assert -1 <= x0 < 1
        return Fraction(1e8) * (x0 + Fraction(c) * (2 * k + 1))
    return Fraction(1e8) * (x0 + Fraction(c) if x0 >= 0 else x0 - Fraction(c))


def test_an_if_else_jump_across_zero_is_no_equilibrium():
    # f1 = 1e8 if_else(x >= 0, x + c, x - c), c = float 1e-13: f1 >= 1e8 c = 1e-5 for x >= 0 and
    # f1 <= -1e-5 for x < 0, exactly; no zero anywhere. The fallback for fields the interval
    # flags do not show continuous asks |f(z)| <= max|J| 1e-12 (1 + |z|) = 1e-4 and
    # |f(z)| < 1e-9 span = 2e-5: 1e974a7 reports (0, 0) "degenerate", where f1 = 1e-5.
    X, Y = _X[0], _X[1]
    c = 1e-13
    eqs = _eqs(cs.vertcat(1e8 * cs.if_else(X >= 0, X + c, X - c), -Y), region=RB)
    for s in _states(eqs):
        f1 = _exact_jump_field(s, c)
        assert f1 == 0, (s, float(f1))
    assert eqs == [], _states(eqs)


def test_a_floor_jump_across_zero_is_no_saddle():
    # f1 = 1e8 (x + c (2 floor(x) + 1)), c = float 1e-13: 1e8 (x + c) >= 1e-5 on [0, 1) and
    # 1e8 (x - c) <= -1e-5 on [-1, 0): no zero in (-1, 1). 1e974a7 reports (1.8e-17, 0) as the
    # target, kind "saddle" (f1 = 1.00002e-5 there).
    X, Y = _X[0], _X[1]
    c = 1e-13
    eqs = _eqs(cs.vertcat(1e8 * (X + c * (2 * cs.floor(X) + 1)), -Y), region=RB)
    for s in _states(eqs):
        if -1 <= s[0] < 1:
            f1 = _exact_jump_field(s, c, floor=True)
            assert f1 == 0, (s, float(f1))
    assert [s for s in _states(eqs) if -1 <= s[0] < 1] == [], [
        (e.state.tolist(), e.kind) for e in eqs]


# ---------------------------------------------------------------- estimate_roa's final certificate loop

def test_estimate_roa_does_not_call_a_valid_local_candidate_a_counterexample():
    # A saturated PD loop xdot = y, ydot = -sat(4x + 2y) + 0.4 x^3 (sat: fmin/fmax to [-1, 1]),
    # V = x' P x with P = [[3/2, 1/8], [1/8, 5/16]], which solves A'P + PA = -I exactly for the
    # linear part A = [[0, 1], [-4, -2]]. On {V <= 0.01}: lambda_min(P) > 0.29, so |x| < 0.186,
    # |4x + 2y| <= sqrt(20) |x| < 0.84 (unsaturated) and
    # Vdot = -|x|^2 + 0.8 x^3 (x/8 + 5y/16) <= -|x|^2 + 0.27 |x|^4 < 0 off the origin:
    # {V <= 0.01} is a region of attraction (check_lyapunov's certificate proves it too).
    # 1e974a7: the bisection ends at 0.1438, the final loop's 10 certificate runs each find a
    # Vdot > 0 state a hair lower (V = 0.1435 ... 0.1402), and the result is level 0.0, status
    # "counterexample", counterexample (-0.23987, -0.33032) where V = 0.14021 > 0 = the level.
    X, Y = _X[0], _X[1]
    f = cs.vertcat(Y, -cs.fmax(cs.fmin(4 * X + 2 * Y, 1), -1) + 0.4 * X ** 3)
    V = 1.5 * X ** 2 + 0.25 * X * Y + 0.3125 * Y ** 2
    P = [[Fraction(3, 2), Fraction(1, 8)], [Fraction(1, 8), Fraction(5, 16)]]
    A = [[0, 1], [-4, -2]]
    Q = [[sum(A[k][i] * P[k][j] + P[i][k] * A[k][j] for k in range(2)) for j in range(2)]
         for i in range(2)]
    assert Q == [[-1, 0], [0, -1]]
    r = _roa((_X, f), V, equilibrium=[0, 0], region={"x_0": (-3, 3), "x_1": (-3, 3)},
             confirm=50)
    if r.status == "counterexample":
        c0, c1 = (Fraction(float(v)) for v in np.asarray(r.counterexample, dtype=float))
        v_cex = P[0][0] * c0 ** 2 + 2 * P[0][1] * c0 * c1 + P[1][1] * c1 ** 2
        assert v_cex <= Fraction(r.level), (r.level, r.counterexample, float(v_cex))
    assert r.level >= 0.01, (r.level, r.status, r.counterexample)


# ---------------------------------------------------------------- classification off the zero's box

def test_a_double_zero_behind_rounding_is_not_stable():
    # f = (-2 (1 - cos x), -y): the only zero with |x| < 2 pi is the origin, where
    # J = diag(-2 sin 0, -1) = diag(0, -1): not hyperbolic (the docstring's "degenerate"), and
    # unstable: f1 < 0 for every x in [-1, 0), so a start at x < 0 decreases for ever (to -2 pi).
    # 1e974a7 reports (9.14e-9, 0), is_target, "stable", eigenvalues (-1.83e-8, -1): there
    # 1 - cos(x) rounds to 0 (the point enclosure holds 0), the zero box has radius 2e-9, and the
    # Jacobian's spread over that box (4e-9) is below 1.83e-8.
    from scipy.integrate import solve_ivp

    X, Y = _X[0], _X[1]
    eqs = _eqs(cs.vertcat(-2 * (1 - cs.cos(X)), -Y), region={"x_0": (-1, 1), "x_1": (-1, 1)})
    # instability, independently: xdot = -2 (1 - cos x) from x = -0.1 passes -1 by t = 10
    sol = solve_ivp(lambda t, z: [-2 * (1 - np.cos(z[0]))], (0, 10), [-0.1], rtol=1e-10,
                    atol=1e-13)
    assert sol.y[0, -1] < -1
    assert not [e for e in eqs if e.kind == "stable"], [
        (e.state.tolist(), e.kind, e.eigenvalues.tolist()) for e in eqs]


# ---------------------------------------------------------------- lyapunov_equation_candidate

def test_a_singular_linearization_is_not_hurwitz():
    # A = [[-1, 1/2, 0], [0, -1, 1], [2, 0, -1]]: det(A) = -1 + 1/2 * 2 = 0 exactly (char.
    # polynomial (s + 1)^3 - 1), so 0 is an eigenvalue and A' P + P A = -I has no positive
    # definite solution; the docstring promises HybridnavError. 1e974a7 returns V with
    # eig(P) = (-4.5e15, 0.245, 0.755).
    from hybridnav.analysis import lyapunov_equation_candidate
    from hybridnav.errors import HybridnavError

    x3 = cs.SX.sym("x", 3)
    a, b, c = x3[0], x3[1], x3[2]
    A = [[-1, Fraction(1, 2), 0], [0, -1, 1], [2, 0, -1]]
    det = (A[0][0] * (A[1][1] * A[2][2] - A[1][2] * A[2][1])
           - A[0][1] * (A[1][0] * A[2][2] - A[1][2] * A[2][0])
           + A[0][2] * (A[1][0] * A[2][1] - A[1][1] * A[2][0]))
    assert det == 0
    f = cs.vertcat(-a + 0.5 * b, -b + c, 2 * a - c)
    with pytest.raises(HybridnavError, match="the linearization at the target is not Hurwitz"):
        lyapunov_equation_candidate((x3, f), equilibrium=[0, 0, 0])


def test_may_step_tells_jumps_from_continuous_operations():
    from hybridnav.analysis.interval import may_step

    x = _X[0]
    assert not may_step(_X, cs.vertcat(cs.sqrt(x ** 2 + 1e-300), cs.fmin(x, 1), cs.fabs(x),
                                       cs.constpow(x ** 2, 1.0 / 3)))
    for f in (cs.if_else(x >= 0, x, -x), cs.floor(x), cs.sign(x), cs.atan2(x, _X[1])):
        assert may_step(_X, f), f


def test_a_jump_across_zero_is_refused_and_a_kink_through_zero_kept():
    # the same if_else, once jumping across 0 (no zero) and once continuous through 0 (a zero)
    X, Y = _X[0], _X[1]
    jump = _eqs(cs.vertcat(cs.if_else(X >= 0, X + 1e-3, X - 1e-3), -Y))
    kink = _eqs(cs.vertcat(cs.if_else(X >= 0, -X, -3 * X), -Y))
    assert jump == [], _states(jump)
    assert [e.state.tolist() for e in kink] == [[0.0, 0.0]], _states(kink)
