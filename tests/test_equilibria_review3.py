"""Second hostile review of find_equilibria at 838205f (the interval zero tests, the
Bauer-Fike classification, the deduplication).

Each test states the exact fact it checks (closed-form zeros, sympy eigenvalues); all fail on
838205f.

- Classification: a defective (Jordan-block) but hyperbolic Jacobian -- the critically damped
  PD-controlled double integrator -- is "degenerate": eig returns (nearly) parallel eigenvectors,
  so cond(V) is ~1e8..inf and the Bauer-Fike tolerance swallows every eigenvalue. 1972685~1
  said "stable". (Also the built-in unicycle's target: eigenvalues -0.5, -1, -1.)
- Over-claims: the centred-form exclusion is skipped for the whole field as soon as one
  component has a kink (fabs) on the box, so the first review's dependency fakes come back with
  a harmless -y - |y|/2 as second component (and estimate_roa is bounded by one); a field written
  with if_else passes through the residual fallback though it has no zero.
- Dedup/is_target: both use 1e-6 * span, the largest side of the region, so in a region long in
  one state, distinct equilibria 0.01 apart are one, and the one kept is called the target
  (estimate_roa then claims a level holding a second stable equilibrium).
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

# ---------------------------------------------------------------- classification: Jordan blocks

@pytest.mark.parametrize("k", [1.0, 1e-3])
def test_a_critically_damped_pd_loop_is_stable(k):
    # xdot = v, vdot = -k^2 x - 2k v: J = [[0, 1], [-k^2, -2k]]; sympy: eigenvals {-k: 2},
    # jordan_form block [[-k, 1], [0, -k]] -- defective but hyperbolic, asymptotically stable.
    # 838205f: "degenerate" (cond of eig's eigenvector matrix ~1e8 or inf); 1972685~1: "stable"
    X, V = _X[0], _X[1]
    eqs = _eqs(cs.vertcat(V, -k * k * X - 2 * k * V))
    assert [e.kind for e in eqs] == ["stable"]


def test_a_critically_damped_pendulum_is_stable():
    # xdot = v, vdot = -sin x - 2v: at the origin J = [[0, 1], [-1, -2]], eigenvalue -1 twice
    # (Jordan block); the other equilibria x = +-pi are outside the region
    X, V = _X[0], _X[1]
    eqs = _eqs(cs.vertcat(V, -cs.sin(X) - 2 * V))
    assert [(e.kind, e.is_target) for e in eqs] == [("stable", True)]


def test_a_four_dimensional_jordan_block_is_stable():
    # xdot = A x, A = -I + N (N the shift): sympy eigenvals {-1: 4}, one Jordan block; stable
    x = cs.SX.sym("x", 4)
    A = -np.eye(4) + np.eye(4, k=1)
    eqs = _eqs(cs.mtimes(cs.DM(A), x), region={f"x_{i}": (-2, 2) for i in range(4)}, x=x,
               equilibrium=(0, 0, 0, 0), starts=50)
    assert [e.kind for e in eqs] == ["stable"]


# ---------------------------------------------------------------- over-claims (no zero exists)

def test_a_kink_in_another_component_does_not_readmit_a_cancelling_field():
    # f1 = 1e12 (exp(x) - 1 - x + 1e-12) >= 1 for every real x (exp(x) >= 1 + x): no
    # equilibrium. f2 = -y - |y|/2 only adds a kink at y = 0, which turns the centred form off
    # for the whole field; 838205f reports (7.7e-8, 0) (f1 = 1.0 there) as the "degenerate"
    # target; 1972685~1 reported nothing.
    X, Y = _X[0], _X[1]
    eqs = _eqs(cs.vertcat(1e12 * (cs.exp(X) - 1 - X + 1e-12), -Y - 0.5 * cs.fabs(Y)))
    assert eqs == [], _states(eqs)


def test_an_expanded_polynomial_with_a_kink_has_only_its_true_zero():
    # f1 = -1e6 x ((x - 1)^2 + 1e-9) vanishes only at x = 0; f2 = -y - |y|/2 only at y = 0.
    # 838205f adds (0.999998, 0) and (1.0000055, 0), where f1 = -1e-3 and -1.6e-3
    X, Y = _X[0], _X[1]
    eqs = _eqs(1e6 * cs.vertcat(-(X ** 3 - 2 * X ** 2 + (1 + 1e-9) * X),
                                -Y - 0.5 * cs.fabs(Y)))
    assert _states(eqs) == [[0.0, 0.0]]


def test_estimate_roa_is_not_bounded_by_a_non_equilibrium_behind_a_kink():
    # V = x^2 + y^2: Vdot = -2x^2((x-1)^2 + 1e-9) + 2y(-y - |y|/2) < 0 off the origin, the only
    # equilibrium. 838205f: level 0.999, bounded_by "equilibrium", counterexample (0.9999981, 0)
    # where f1 = -1.0e-9
    X, Y = _X[0], _X[1]
    f = cs.vertcat(-(X ** 3 - 2 * X ** 2 + (1 + 1e-9) * X), -Y - 0.5 * cs.fabs(Y))
    r = _roa((_X, f), X ** 2 + Y ** 2, equilibrium=[0, 0], region=_R)
    assert r.bounded_by != "equilibrium", (r.level, r.counterexample)


def test_an_if_else_field_without_a_zero_has_no_equilibrium():
    # f1 = if_else(x > 0, x, -x) + 5e-10 = |x| + 5e-10 >= 5e-10 > 0: no equilibrium. Newton
    # oscillates between -5e-10 and 5e-10; the box around the end point straddles the if_else,
    # so only the residual fallback decides (|f| = 1e-9 < 1e-9 span) and 838205f reports
    # (-5e-10, 0) as the target
    X, Y = _X[0], _X[1]
    eqs = _eqs(cs.vertcat(cs.if_else(X > 0, X, -X) + 5e-10, -Y))
    assert eqs == [], _states(eqs)


# ---------------------------------------------------------------- dedup / is_target

_LONG = {"x_0": (-0.1, 0.1), "x_1": (-2e4, 2e4)}     # span 4e4: 1e-6 span = 0.04


def _double_well():
    # V = 1250 x^4 - 50 x^3 + x^2/2 + y^2/2, f = -grad V = (-5000 x (x - 0.01)(x - 0.02), -y):
    # equilibria (0, 0) stable (J = diag(-1, -1)), (0.01, 0) saddle (f1' = 0.5), (0.02, 0)
    # stable (f1' = -1); V(0.01, 0) = 1.25e-5, V(0.02, 0) = 0
    X, Y = _X[0], _X[1]
    V = 1250 * X ** 4 - 50 * X ** 3 + X ** 2 / 2 + Y ** 2 / 2
    return V, -cs.gradient(V, _X)


def test_equilibria_a_hundredth_apart_are_not_merged():
    # 838205f reports one, (0.02, 0), as the "stable" target; the target (0, 0) and the saddle
    # are swallowed by the 1e-6 * span dedup (1972685~1 the same)
    _, f = _double_well()
    eqs = _eqs(f, region=_LONG)
    got = sorted((round(float(e.state[0]), 6), e.kind, e.is_target) for e in eqs)
    assert got == [(0.0, "stable", True), (0.01, "saddle", False), (0.02, "stable", False)]


def test_estimate_roa_does_not_cover_another_stable_equilibrium():
    # the level must stay below V(0.01, 0) = 1.25e-5 (the saddle; and {V < c} for c > 0 holds
    # the stable equilibrium (0.02, 0), V = 0, which never reaches the origin). 838205f:
    # level 8081.95, status "no_counterexample", bounded_by "box"
    V, f = _double_well()
    r = _roa((_X, f), V, equilibrium=[0, 0], region=_LONG)
    assert r.level < 1.25e-5, (r.level, r.status, r.bounded_by)
