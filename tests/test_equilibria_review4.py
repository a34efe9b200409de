"""Third hostile review of find_equilibria at 88a2b8e (zero box, Lipschitz fallback, the
pseudospectral classification). Each test states the exact fact it checks; all fail on 88a2b8e.

- The zero box z +- 1e-9 (1 + |z|) is 0.1 wide at |z| = 1e8: two simple equilibria 0.15 apart
  there have overlapping boxes, so the second is merged into the first (missed), and the kept
  one is "degenerate" (the Jacobian's spread over the 0.2-wide box exceeds its eigenvalue).
  1972685~1 found both (stable target, saddle) and estimate_roa proved 0.02248 < 0.0225.
- The classification's rounding term 1e-13 ||J|| is normwise, so a linear Hurwitz cascade with an
  exact Jacobian [[-1, 1e7], [0, -1]] is "degenerate" -- and rescaling y (units) makes it
  "stable". 1972685~1: "stable".
- The Lipschitz residual fallback for if_else fields accepts a field that is >= 0.25 everywhere
  (the if_else is enclosed as the hull of both branches on the whole box, and the steep
  branches make the Lipschitz reach 1).
"""

from __future__ import annotations

import casadi as cs
import pytest

from equilibria_cases import X as _X
from equilibria_cases import eqs as _eqs
from equilibria_cases import roa as _roa
from equilibria_cases import states as _states

# ---------------------------------------------------------------- zero box at large |z|

_A, _B = 1e8, 1e8 + 0.15           # both exact in binary64 to ~1.5e-8
_FAR = {"x_0": (_A - 1, _A + 1), "x_1": (-1, 1)}


def _far_field():
    # f = (-(x - a)(x - b), -y): simple zeros (a, 0) and (b, 0) only. Exact Jacobians:
    # at a diag(0.15, -1) (saddle), at b diag(-0.15, -1) (stable; sympy eigenvals {-3/20, -1})
    X, Y = _X[0], _X[1]
    return cs.vertcat(-(X - _A) * (X - _B), -Y)


def test_two_equilibria_far_from_the_origin_are_both_found():
    # 88a2b8e: only (1e8 + 0.15, 0) "degenerate"; the zero boxes (radius 1e-9 (1 + 1e8) = 0.1)
    # overlap, so the saddle at 1e8 is merged away. 1972685~1: stable target + saddle
    eqs = _eqs(_far_field(), region=_FAR, equilibrium=(_B, 0))
    got = sorted((round(float(e.state[0]) - _A, 6), e.kind, e.is_target) for e in eqs)
    assert got == [(0.0, "saddle", False), (0.15, "stable", True)]


def test_estimate_roa_far_from_the_origin_is_not_zero():
    # V = (x - b)^2 + y^2: Vdot = -2 (x - b)^2 (x - a) - 2 y^2 < 0 for x > a off (b, 0), so every
    # level below (b - a)^2 = 0.0225 is a true ROA estimate; 1972685~1 proved 0.02248,
    # 88a2b8e returns level 0 ("counterexample"), having lost the saddle and called the target
    # degenerate
    X, Y = _X[0], _X[1]
    r = _roa((_X, _far_field()), (X - _B) ** 2 + Y ** 2, equilibrium=[_B, 0],
                         region=_FAR)
    assert 0.02 < r.level < 0.0225, (r.level, r.status, r.bounded_by)


# ---------------------------------------------------------------- classification, non-normal

@pytest.mark.parametrize("gain", [1e7])
def test_a_linear_hurwitz_cascade_is_stable_whatever_its_units(gain):
    # x' = -x + gain y, y' = -y: J = [[-1, gain], [0, -1]] exactly (a linear field: interval
    # spread 0); sympy eigenvals {-1: 2}, Jordan block -- hyperbolic, globally exponentially
    # stable, and similar (y -> gain y) to [[-1, 1], [0, -1]]. 88a2b8e: gain 1e7 "degenerate"
    # (sigma_min(J) ~ 1e-7 <= 1e-13 ||J|| = 1e-6), gain 1e5 "stable"; 1972685~1: both "stable"
    X, Y = _X[0], _X[1]
    eqs = _eqs(cs.vertcat(-X + gain * Y, -Y))
    assert [e.kind for e in eqs] == ["stable"]


# ---------------------------------------------------------------- Lipschitz fallback

def test_a_positive_if_else_field_with_steep_branches_has_no_equilibrium():
    # f1 = if_else(x > 0, 1e12 x + 0.25, -1e12 x + 0.5) >= 0.25 for every real x (each branch is
    # positive on its own side): no equilibrium. Newton ends at x = -2.5e-13 where f1 = 0.75;
    # the fallback's reach is max|J| 1e-12 (1 + |z|) = 1, so 88a2b8e reports (-2.5e-13, 0).
    # Enclosing each branch on its own part of the box ((0, r] and [-r, 0]) excludes a zero.
    X, Y = _X[0], _X[1]
    eqs = _eqs(cs.vertcat(cs.if_else(X > 0, 1e12 * X + 0.25, -1e12 * X + 0.5), -Y))
    assert eqs == [], _states(eqs)
