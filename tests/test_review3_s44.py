"""Adversarial review 3 of s44: find_equilibria after 7364ffb (a point is 0 to rounding only where
the jumping components are decided; a sign change between adjacent floats within the Jacobian's
bound; splits only along splittable states; a bisection budget of 400 rounds per call). Every case
was a strict xfail that failed because of the defect it names; the claims are justified by exact
arithmetic (fractions.Fraction on the float constants the CasADi expressions hold). All are fixed:
the fast test asks that the jumping components be decided at z (or exactly 0), the adjacent-floats
rule is gone, the centred form's radius covers the part, and the rounds of an accepted point's
bisection are given back to the budget.

C1. (false acceptance) The fast "f(z) is 0 to rounding" test in ``_ZeroTests.accepted`` runs
    before any bisection and never asks whether the jumping components are decided at z: a
    Newton end exactly on a float where an if_else condition is rounding-undecided gets the hull
    of both branches, which holds 0. A jump from -1 to +2^-54/3 across 0 is reported
    (7364ffb's decided-point rule only guards the points of bisected parts).
C2. (false acceptance) The adjacent-floats rule (``_crossing``) accepts any jump across 0 no
    larger than the Jacobian's *enclosure* times the width -- but the enclosure is an
    over-estimate (interval dependency), not a slope the field has. A jump of 2 between two
    adjacent floats, beside a branch whose real slope there is <= 0.2 but whose enclosure is
    2, is reported as an equilibrium (d1d88e0 refused it).
C3. (miss) ``_subdivided`` evaluates the centred form of a part at the rounded midpoint
    ``c = fl((lo + hi) / 2)`` with half-width ``fl((hi - lo) / 2)``: ``c +- r`` is not the part
    when the midpoint rounds (half an ulp of c off). A zero on a bisection point (x = 1 here)
    falls out of both neighbouring parts' boxes, both are excluded, and the plain isolated
    zero (1, 0) of ((x - 1)^2 + y^2, x - 1) is refused (d1d88e0 found it).
C4. (miss) The 400-round budget is spent on real zeros: six degenerate zeros of
    (sin(3 pi x)^3, y) are each bisected for the full 64 rounds, the seventh Newton end (at the
    origin, the system's own equilibrium, where f is exactly (0, 0)) gets 16 rounds and is
    marked undecided, and every later Newton end near it is refused. The origin is missed
    (d1d88e0 found all 13 zeros; with SUBDIVIDE_BUDGET = 10**5, 7364ffb finds all 13 too).
"""

from __future__ import annotations

from fractions import Fraction

import casadi as cs
import numpy as np
import pytest

from equilibria_cases import X as _X
from equilibria_cases import eqs as _eqs
from equilibria_cases import states as _states


def _q(v) -> Fraction:
    return Fraction(float(v))


# ---------------------------------------------------------------- C1. the fast path at z

def test_a_newton_end_on_an_undecided_condition_is_no_zero():
    # f = (if_else(3x - 1 >= 0, x - p, x - p - 1), -y), p = fl(1/3) = 6004799503160661 / 2^54.
    # For every real x: 3x - 1 >= 0 <=> x >= 1/3, and then f1 = x - p >= 1/3 - p = 1/(3 2^54) > 0;
    # otherwise x < 1/3 and f1 = x - p - 1 < 1/3 - p - 1 < 0. No zero anywhere.
    # In floats, fl(3p) = fl(1 - 2^-54) = 1 (a tie, to even), so the float condition holds at p
    # and f(p, 0) = (p - p, -0) = (0, 0): Newton ends exactly at (p, 0). hybridnav reports
    # (0.3333333333333333, 0.0) 'degenerate' (d1d88e0 too). The interval value at z = (p, 0):
    # 3p - 1 is [-2^-53, 0] outward rounded, the condition is undecided (continuity flag False)
    # and f1's enclosure is the hull [-1, 0] of both branches, which holds 0 -- and accepted()
    # returns True on "np.all((fl <= 0) & (fh >= 0))" before the decided check of _subdivided.
    p = 1 / 3
    assert _q(p) == Fraction(6004799503160661, 2 ** 54)
    assert Fraction(1, 3) - _q(p) == Fraction(1, 3 * 2 ** 54)
    X, Y = _X[0], _X[1]
    eqs = _eqs(cs.vertcat(cs.if_else(3 * X - 1 >= 0, X - p, X - p - 1), -Y))
    for s in _states(eqs):
        x0 = _q(s[0])
        f1 = x0 - _q(p) if 3 * x0 - 1 >= 0 else x0 - _q(p) - 1
        assert f1 != 0, (s, float(f1))
    assert eqs == [], [(e.state.tolist(), e.kind) for e in eqs]


# ---------------------------------------------------------------- C2. _crossing on an over-estimate

_A = 2.0 ** 52 + 1                  # floats are spaced 1 in [2^52, 2^53)


@pytest.mark.parametrize("a, K, region", [
    (_A, 1.0, {"x_0": (_A - 100, _A + 100), "x_1": (-1, 1)}),
    (1.0, 2.0 ** 212, None),
], ids=["at-2^52-K1", "at-1-K2^212"])
def test_a_jump_within_an_overestimated_slope_bound_is_no_zero(a, K, region):
    # f = (if_else(x >= a, 1, -1 - K ((x - p)(x - a))^2), -y), p the float below a.
    # For every real x >= a, f1 = 1; for x < a, f1 = -1 - K (...)^2 <= -1: |f1| >= 1 everywhere,
    # no zero. hybridnav reports one 'degenerate' equilibrium (4503599627370524.0, 0.0) for the
    # first case (its zero box, 64 ulps = 64 wide, holds a), (0.9999999999999993, 0.0) for the
    # second. The part [p, a] (adjacent floats, width u) survives: the if_else is undecided on
    # it (hull [-1 - K u^4, 1] holds 0). The decided points p (f1 = -1) and a (f1 = 1) rise by 2.
    # f1's Jacobian enclosure on [p, a]: 2K ((x - p)(x - a)) ((x - a) + (x - p)) with
    # (x - p)(x - a) in [-u^2, 0] and the sum in [-u, u], so L = 2K u^3 and L u = 2K u^4 = 2:
    # _crossing's rise <= reach holds. The real derivative of the branch on [p, a] is at most
    # 2K u^3 max |t (1 - t)(2t - 1)| = 2K u^3 / (6 sqrt 3) < L / 10: no function with the field's
    # real slopes climbs 2 over [p, a]. (K = 0 and, in the second case, K = 2^200 are refused;
    # d1d88e0 refuses both.)
    p = float(np.nextafter(a, -np.inf))
    u = _q(a) - _q(p)
    assert u == (1 if a == _A else Fraction(1, 2 ** 53))
    assert 2 * _q(K) * u ** 4 == 2                         # reach L u = rise = 1 - (-1)
    kw = {"equilibrium": (a, 0.0)}
    if region is not None:
        kw["region"] = region
    X, Y = _X[0], _X[1]
    eqs = _eqs(cs.vertcat(cs.if_else(X >= a, 1.0, -1.0 - K * ((X - p) * (X - a)) ** 2), -Y), **kw)
    for s in _states(eqs):
        x0 = _q(s[0])
        f1 = Fraction(1) if x0 >= _q(a) else -1 - _q(K) * ((x0 - _q(p)) * (x0 - _q(a))) ** 2
        assert abs(f1) >= 1, (s, float(f1))
    assert eqs == [], [(e.state.tolist(), e.kind) for e in eqs]


# ---------------------------------------------------------------- C3. the rounded midpoint

def test_a_degenerate_zero_on_a_bisection_point_is_found():
    # f = ((x - 1)^2 + y^2, x - 1). f(1, 0) = (0, 0) exactly; isolated: f2 = 0 forces x = 1, and
    # then f1 = y^2 = 0 forces y = 0. Degenerate (J(1, 0) = [[0, 0], [1, 0]]), so Krawczyk cannot
    # prove it; Newton ends at (1.0, -3.5e-32), f1 = 1.2e-63 > 0 there (not 0 to rounding), and
    # the zero box x in [fl(1 - 4e-9), fl(1 + 4e-9)] is bisected, first at x = 1 exactly.
    # hybridnav reports [] (d1d88e0: (1.0, -3.5e-32) 'degenerate'). The right part [1, hi],
    # hi = fl(1 + 4e-9): c = fl((1 + hi)/2), r = (hi - 1)/2, and c - r = 1 + 2^-53 > 1, so the
    # centred form of f2 = x - 1 (slope exactly 1) on c +- r is >= 2^-53 > 0 (its 1e-12 relative
    # slack is ~4e-21): excluded. The left neighbour [fl(1 - 1e-9)..., 1] likewise has
    # c + r = 1 - 2^-54 < 1 and f2 <= -2^-54 on c +- r: excluded. No part holds x = 1 any more,
    # "every part excludes a zero", and the point is refused. (With r = max(c - lo, hi - c)
    # the zero is found.)
    lo0, hi0 = 1.0 - 4e-9, 1.0 + 4e-9
    assert (lo0 + hi0) / 2 == 1.0
    c, r = (1.0 + hi0) / 2, (hi0 - 1.0) / 2
    assert _q(c) - _q(r) - 1 == Fraction(1, 2 ** 53)
    lo = lo0
    for _ in range(2):
        lo = (lo + 1.0) / 2
    c, r = (lo + 1.0) / 2, (1.0 - lo) / 2
    assert _q(c) + _q(r) - 1 == -Fraction(1, 2 ** 54)
    X, Y = _X[0], _X[1]
    eqs = _eqs(cs.vertcat((X - 1) ** 2 + Y ** 2, X - 1))
    assert [s for s in _states(eqs) if abs(s[0] - 1) < 1e-6 and abs(s[1]) < 1e-6], _states(eqs)


# ---------------------------------------------------------------- C4. the budget spent on real zeros

def test_the_equilibrium_after_six_degenerate_zeros_is_found():
    # f = (sin(c x)^3, y), c = fl(3 fl(pi)). f(0, 0) = (0, 0) exactly (the equilibrium passed to
    # find_equilibria). Isolated: f2 = 0 forces y = 0, and sin(c x) != 0 for 0 < |x| < pi / c
    # (~1/3). The zeros in [-2, 2]^2 are (k pi / c, 0), k = -6..6, all degenerate (f1 cubic).
    # hybridnav reports the twelve with k != 0 and misses the origin (d1d88e0 reports all 13;
    # 7364ffb with SUBDIVIDE_BUDGET = 10**5 does too). The Newton ends at k = 2, 4, 1, 3, -2, -4
    # come first, are not 0 to rounding, and are each bisected the full 64 rounds (accepted:
    # a continuous part left): 384 rounds. The origin's first Newton end gets the last 16 rounds,
    # is marked undecided, and the later ones meet its box and are refused.
    c = 3 * np.pi
    assert np.sin(c * 0.0) == 0.0
    assert _q(c) > 9 and _q(c) < 10                      # pi / c in (0.31, 0.35)
    X, Y = _X[0], _X[1]
    eqs = _eqs(cs.vertcat(cs.sin(c * X) ** 3, Y))
    assert [s for s in _states(eqs) if max(abs(s[0]), abs(s[1])) < 1e-6], _states(eqs)
