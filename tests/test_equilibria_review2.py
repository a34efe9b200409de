"""Hostile review of 1972685 (find_equilibria's interval zero test, its eigenvalue classification).

Each test states the exact fact it checks against (closed-form zeros and eigenvalues); all of them
fail on 1972685.

Over-claims: the test "the enclosure of every component holds 0 on z +- 1e-9 (1 + |z|)" is
componentwise and suffers interval dependency, so it is neither scale-free nor a zero test:
- dependency: ``exp(x) - 1 - x`` or an expanded polynomial encloses to a width ~ r * (sum of the
  terms' slopes), however small ``f'`` is, so a scaled field with ``|f| >= 1`` passes;
- componentwise: ``f1 = 0`` and ``f2 = 0`` each have solutions in the box but not a common one.
Misses: a continuous field whose zero Newton approaches linearly (a double zero behind an
``if_else``, ``sqrt``, a fractional power) ends a hair away from it; the box then holds a
"jump"/non-Lipschitz operation and the point value is not 0, so the true equilibrium (here the
target) is refused; 1972685~1 found all of them.
Classification: "degenerate" when a real part <= 1e-10 max|eig| calls hyperbolic stiff or
fast-rotating equilibria degenerate, and misses the 1-D -x^3 and a nilpotent Jacobian.
"""

from __future__ import annotations

import casadi as cs
import numpy as np
import pytest

from equilibria_cases import R as _R
from equilibria_cases import X as _X
from equilibria_cases import eqs as _eqs
from equilibria_cases import roa as _roa
from equilibria_cases import states as _states

# ---------------------------------------------------------------- over-claims (no zero exists)

def test_cancelling_terms_do_not_make_a_fast_field_vanish():
    # exp(x) >= 1 + x for every real x, so f1 = 1e12 (exp(x) - 1 - x + 1e-12) >= 1 everywhere:
    # the system has no equilibrium at all. 1972685 reports x ~ 7.7e-8 (f1 = 1.0 there) as a
    # "saddle"; 1972685~1 reported nothing.
    X, Y = _X[0], _X[1]
    eqs = _eqs(cs.vertcat(1e12 * (cs.exp(X) - 1 - X + 1e-12), -Y))
    assert eqs == [], _states(eqs)


def test_an_expanded_polynomial_has_only_its_true_zero():
    # f1 = -1e6 (x^3 - 2x^2 + (1 + 1e-9) x) = -1e6 x ((x - 1)^2 + 1e-9): the only zero is x = 0.
    # 1972685 adds x = 0.999998 ("saddle") and x = 1.000002 ("stable") where f1 = -1e-3.
    X, Y = _X[0], _X[1]
    eqs = _eqs(1e6 * cs.vertcat(-(X ** 3 - 2 * X ** 2 + (1 + 1e-9) * X), -Y))
    assert _states(eqs) == [[0.0, 0.0]]


def test_estimate_roa_is_not_bounded_by_a_non_equilibrium():
    # the same field (unscaled): V = x^2 + y^2 has Vdot = -2x^2((x-1)^2 + 1e-9) - 2y^2 < 0 off the
    # origin, the only equilibrium. 1972685: level 0.999, bounded_by "equilibrium", counterexample
    # (0.9999981, 0) where f = (-1.0e-9, 0) and Vdot = -2.0e-9.
    X, Y = _X[0], _X[1]
    f = cs.vertcat(-(X ** 3 - 2 * X ** 2 + (1 + 1e-9) * X), -Y)
    r = _roa((_X, f), X ** 2 + Y ** 2, equilibrium=[0, 0], region=_R)
    assert r.bounded_by != "equilibrium", (r.level, r.counterexample)


def test_a_large_region_does_not_admit_a_cancelling_quadratic():
    # f1 = x^2 - 2e7 x + 1e14 + 1e3 = (x - 1e7)^2 + 1e3 >= 1e3: no equilibrium. 1972685 reports
    # x = 10000001.8 (f1 = 1003.4 there, a "saddle").
    X, Y = _X[0], _X[1]
    eqs = _eqs(cs.vertcat(X ** 2 - 2e7 * X + 1e14 + 1e3, -Y),
               region={"x_0": (-1e8, 1e8), "x_1": (-2, 2)})
    assert eqs == [], _states(eqs)


def test_parallel_nullclines_have_no_equilibrium():
    # f1 - f2 = 1e-10 identically: no common zero anywhere; 1972685 reports four "unstable" ones
    X, Y = _X[0], _X[1]
    eqs = _eqs(cs.vertcat(X - Y, X - Y - 1e-10))
    assert eqs == [], _states(eqs)


def test_nullclines_that_miss_each_other_have_no_equilibrium():
    # ydot = -y = 0 forces y = 0, then xdot = -x^2 - 5e-10 < 0: no equilibrium; 1972685 reports
    # x = +-3e-6 (a "stable" and a "saddle" one)
    X, Y = _X[0], _X[1]
    eqs = _eqs(cs.vertcat(Y - X ** 2 - 5e-10, -Y))
    assert eqs == [], _states(eqs)


# ---------------------------------------------------------------- misses (regressions)

def _has_origin(eqs):
    return any(np.linalg.norm(np.asarray(e.state, dtype=float)) < 1e-6 for e in eqs)


@pytest.mark.parametrize("name", ["if_else", "sqrt_norm", "fractional_power"])
def test_a_continuous_fields_zero_is_kept(name):
    # every field below is continuous, vanishes exactly at the origin (the target) and nowhere
    # else in the region; 1972685~1 found the origin in each, 1972685 returns nothing
    X, Y = _X[0], _X[1]
    r = cs.sqrt(X ** 2 + Y ** 2)
    f = {"if_else": cs.vertcat(cs.if_else(X >= 0, -X ** 2, X ** 2), -Y),        # -x|x|
         "sqrt_norm": cs.vertcat(-X * r, -Y * r),
         "fractional_power": cs.vertcat(-cs.constpow(X ** 2, 1.0 / 3) * X, -Y),   # -x^(5/3)
         }[name]
    eqs = _eqs(f)
    assert _has_origin(eqs), _states(eqs)
    assert [e.is_target for e in eqs if np.linalg.norm(e.state) < 1e-6] == [True]


def test_a_finite_time_stable_field_does_not_crash():
    # xdot = -sign(x) sqrt|x| is continuous with its only zero at 0, where the Jacobian is
    # infinite: find_equilibria raises numpy's LinAlgError (eigvals of a non-finite matrix);
    # it should report the origin (its linearization decides nothing: "degenerate")
    X, Y = _X[0], _X[1]
    eqs = _eqs(cs.vertcat(-cs.sign(X) * cs.sqrt(cs.fabs(X)), -Y))
    assert _has_origin(eqs)


# ---------------------------------------------------------------- classification

def test_a_stiff_hyperbolic_equilibrium_is_stable():
    # Jacobian diag(-1e-11, -1): exact eigenvalues -1e-11 and -1, both negative (hyperbolic);
    # 1972685 calls it "degenerate" (1972685~1: "stable")
    X, Y = _X[0], _X[1]
    eqs = _eqs(cs.vertcat(-1e-11 * X, -Y))
    assert [e.kind for e in eqs] == ["stable"]


def test_a_fast_damped_rotation_is_stable():
    # Jacobian [[-1, -1e10], [1e10, -1]]: exact eigenvalues -1 +- 1e10 i; 1972685: "degenerate"
    X, Y = _X[0], _X[1]
    eqs = _eqs(cs.vertcat(-X - 1e10 * Y, 1e10 * X - Y))
    assert [e.kind for e in eqs] == ["stable"]


def test_a_one_dimensional_cubic_is_degenerate():
    # xdot = -x^3: f'(0) = 0. The 2-D case of the commit's own test passes, the 1-D one reports
    # "stable" (the Newton end point 2.5e-25 has eigenvalue -1.5e-74, the whole spectrum)
    x = cs.SX.sym("x", 1)
    eqs = _eqs(-x ** 3, region={"x": (-2, 2)}, x=x, equilibrium=(0,))
    assert [e.kind for e in eqs] == ["degenerate"]


def test_a_nilpotent_line_of_equilibria_is_degenerate():
    # f = (x - y, x - y): every point of x = y is an equilibrium, the Jacobian [[1, -1], [1, -1]]
    # is nilpotent (exact eigenvalues 0, 0); 1972685 calls them "unstable"
    X, Y = _X[0], _X[1]
    eqs = _eqs(cs.vertcat(X - Y, X - Y))
    assert eqs and {e.kind for e in eqs} == {"degenerate"}
