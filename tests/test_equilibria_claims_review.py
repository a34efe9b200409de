"""Hostile review: find_equilibria (and estimate_roa through it) must not claim equilibria that
are not ones. Its acceptance test is ``|f(z)| < 1e-9 * max(1, span)``, absolute in the field's
units: a field of small magnitude (a slow system) or a large region (``span``) lets points where
``f != 0`` through, e.g. the minimum of ``|f|`` that a stalled Newton run ends at.

The systems below have exactly one equilibrium, the origin (``(X - 1)^2 + d > 0``)."""

from __future__ import annotations

import warnings

import casadi as cs
import numpy as np
import pytest

from hybridnav.analysis import estimate_roa, find_equilibria

_X = cs.SX.sym("x", 2)


def _system(d, scale=1.0):
    X, Y = _X[0], _X[1]
    return (_X, scale * cs.vertcat(-X * ((X - 1) ** 2 + d), -Y))


def _assert_only_the_origin(eqs):
    states = [np.asarray(e.state, dtype=float) for e in eqs]
    bogus = [s for s in states if np.linalg.norm(s) > 1e-6]
    assert not bogus, f"not equilibria (f != 0 there): {bogus[:3]}"


def test_a_large_region_does_not_turn_a_small_field_value_into_an_equilibrium():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        eqs = find_equilibria(_system(1e-3), equilibrium=[0, 0],
                              region={"x_0": (-1e7, 1e7), "x_1": (-1e7, 1e7)})
    _assert_only_the_origin(eqs)


def test_a_slow_system_has_no_spurious_equilibria():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        eqs = find_equilibria(_system(1e-2, scale=1e-10), equilibrium=[0, 0],
                              region={"x_0": (-2, 2), "x_1": (-2, 2)})
    _assert_only_the_origin(eqs)


def test_estimate_roa_does_not_report_a_non_equilibrium_as_its_counterexample():
    x, f = _system(1e-6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = estimate_roa((x, f), x[0] ** 2 + x[1] ** 2, equilibrium=[0, 0],
                         region={"x_0": (-1e4, 1e4), "x_1": (-1e4, 1e4)})
    # V = |x|^2 decreases everywhere but at the origin (Vdot = -2 X^2 ((X-1)^2 + 1e-6) - 2 Y^2)
    # and the origin is the only equilibrium: nothing but the region bounds the level
    if r.counterexample is not None:
        z = np.asarray(r.counterexample, dtype=float)
        fz = np.asarray(cs.Function("f", [x], [f])(z), dtype=float).ravel()
        vdot = 2 * z @ fz
        assert vdot >= 0 or np.all(fz == 0), (r.bounded_by, z, fz, vdot)


def test_a_fast_system_keeps_its_equilibria():
    # |f| ~ 1e10: Newton's residual at a true zero is ~1e-6, far above an absolute 1e-9
    X, Y = _X[0], _X[1]
    eqs = find_equilibria((_X, 1e10 * cs.vertcat(-X * (X - 1) * (X + 1), -Y)),
                          equilibrium=[0, 0], region={"x_0": (-2, 2), "x_1": (-2, 2)})
    got = sorted((round(float(e.state[0]), 9), e.kind) for e in eqs)
    assert got == [(-1.0, "stable"), (0.0, "saddle"), (1.0, "stable")]


def test_a_zero_eigenvalue_at_rounding_level_is_degenerate():
    # -x^3: Newton ends near 0 where the Jacobian's eigenvalue -3 x^2 is ~1e-70, not "stable"
    X, Y = _X[0], _X[1]
    eqs = find_equilibria((_X, cs.vertcat(-X ** 3, -Y)), equilibrium=[0, 0],
                          region={"x_0": (-2, 2), "x_1": (-2, 2)})
    assert len(eqs) == 1 and eqs[0].kind == "degenerate" and abs(eqs[0].state[0]) < 1e-6


def test_runs_the_rk4_step_loses_are_integrated_again():
    # from |x| ~ 1e4 the cubic field is stiff for RK4 at dt = 0.01 (the runs leave the numbers);
    # CVODES shows they converge: the estimate is the box, not a NaN counterexample
    x, f = _system(1e-6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = estimate_roa((x, f), x[0] ** 2 + x[1] ** 2, equilibrium=[0, 0],
                         region={"x_0": (-1e4, 1e4), "x_1": (-1e4, 1e4)}, grow=0)
    assert r.bounded_by == "box" and r.counterexample is None
    assert r.details["rk4_diverged_cvodes_rerun"] > 0 and r.converged == r.simulated
