"""A fuzzy system as an exact CasADi expression: the same numbers as ``evaluate`` (itself checked
against scikit-fuzzy), exact zeros kept, differentiable where the engine's polyline is."""

from __future__ import annotations

import casadi as cs
import numpy as np
import pytest

from hybridnav import fuzzy
from hybridnav.fuzzy import FuzzySystem

TIPPER = {
    "format": "hybridnav-fis/1", "name": "tipper",
    "inputs": [
        {"name": "service", "range": [0, 10], "points": 201, "terms": [
            {"name": "poor", "mf": "gaussmf", "params": [0, 1.5]},
            {"name": "good", "mf": "trimf", "params": [2, 5, 8]},
            {"name": "excellent", "mf": "trapmf", "params": [7, 9, 10, 11]}]},
        {"name": "food", "range": [0, 10], "points": 101, "terms": [
            {"name": "rancid", "mf": "zmf", "params": [1, 4]},
            {"name": "delicious", "mf": "gbellmf", "params": [2, 3, 8]}]}],
    "output": {"name": "tip", "range": [0, 30], "points": 301, "terms": [
        {"name": "cheap", "mf": "trimf", "params": [0, 5, 10]},
        {"name": "average", "mf": "trapmf", "params": [8, 12, 18, 22]},
        {"name": "generous", "mf": "smf", "params": [18, 28]}],
        "defuzz": "centroid", "default": 15.0},
    "rules": [
        {"if": {"or": [["service", "poor"], ["food", "rancid"]]}, "then": "cheap"},
        {"if": ["service", "good"], "then": "average", "weight": 0.7},
        {"if": {"and": [["service", "excellent"], {"not": ["food", "rancid"]}]},
         "then": "generous"}],
}


def _systems():
    yield from (fuzzy.builtin(n) for n in fuzzy.builtin_names())
    yield FuzzySystem.from_dict(TIPPER)


@pytest.mark.parametrize("system", list(_systems()), ids=lambda s: s.name)
def test_to_casadi_equals_evaluate(system):
    syms = {n: cs.SX.sym(n) for n in system.input_names}
    f = cs.Function("f", list(syms.values()), [system.to_casadi(**syms)])
    rng = np.random.default_rng(7)
    pts = {}
    for v in system.inputs:
        lo, hi = v.range
        x = rng.uniform(lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo), 3000)   # clipping too
        x[:50] = np.linspace(lo, hi, 50)                                     # universe ends
        pts[v.name] = x
    ref = system.evaluate(**pts)
    got = np.asarray(f.map(3000)(*[pts[n][None] for n in system.input_names])).ravel()
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)


def test_a_rule_that_does_not_fire_leaves_the_default_exactly():
    s = fuzzy.builtin("effc-2rule")
    d, a = cs.SX.sym("d"), cs.SX.sym("a")
    f = cs.Function("f", [d, a], [s.to_casadi(dtheta=d, alpha=a)])
    # alpha beyond the 'low' Z-curve and dtheta below the 'high' S-curve: no rule fires
    assert float(f(0.1, 0.9)) == s.output.default == float(s.evaluate(dtheta=0.1, alpha=0.9))


def test_the_expression_differentiates_and_encloses():
    from hybridnav.analysis.interval import IntervalFunction

    s = fuzzy.builtin("effc-tuned")
    d, a = cs.SX.sym("d"), cs.SX.sym("a")
    e = s.to_casadi(dtheta=d, alpha=a)
    x = cs.vertcat(d, a)
    g = cs.Function("g", [x], [cs.gradient(e, x)])
    # a central difference of evaluate agrees with the exact gradient away from the knots
    p = np.array([0.7123, 0.4567])
    h = 1e-6
    num = [(s.evaluate(dtheta=p[0] + h * (i == 0), alpha=p[1] + h * (i == 1))
            - s.evaluate(dtheta=p[0] - h * (i == 0), alpha=p[1] - h * (i == 1))) / (2 * h)
           for i in range(2)]
    np.testing.assert_allclose(np.asarray(g(p)).ravel(), num, rtol=1e-4, atol=1e-7)
    F = IntervalFunction(x, [e])
    lo, hi = np.array([[0.6, 0.4]]), np.array([[0.8, 0.5]])
    ol, oh, _ = F(lo, hi)
    grid = np.stack(np.meshgrid(np.linspace(0.6, 0.8, 21), np.linspace(0.4, 0.5, 21)), -1)
    vals = s.evaluate(dtheta=grid[..., 0], alpha=grid[..., 1])
    assert ol[0, 0] <= vals.min() and vals.max() <= oh[0, 0]


def test_to_casadi_names_its_inputs():
    s = fuzzy.builtin("effc-tuned")
    with pytest.raises(TypeError, match="takes the inputs dtheta, alpha"):
        s.to_casadi(dtheta=cs.SX.sym("d"))


def _one_input(term, out_term, default, points=101, rule=None):
    return FuzzySystem.from_dict({
        "format": "hybridnav-fis/1", "name": "one",
        "inputs": [{"name": "x", "range": [0.0, 1.0], "points": points, "terms": [term]}],
        "output": {"name": "y", "range": [0.0, 1.0], "points": 101, "terms": [out_term],
                   "defuzz": "centroid", "default": default},
        "rules": [{"if": rule or ["x", term["name"]], "then": out_term["name"]}]})


def test_a_plateau_at_one_stays_one_and_a_gaussian_tail_keeps_its_value():
    """NOT of a full membership is exactly 0 (no rule fires: the default), and a membership of
    1e-22 still fires with its value (scikit-fuzzy's answers, checked by the engine's tests)."""
    s = _one_input({"name": "high", "mf": "smf", "params": [0.1, 0.37]},
                   {"name": "low", "mf": "trimf", "params": [0.0, 0.0, 0.5]}, 0.5,
                   rule={"not": ["x", "high"]})
    x = cs.SX.sym("x")
    f = cs.Function("f", [x], [s.to_casadi(x=x)])
    pts = np.linspace(0.37, 1.0, 301)
    np.testing.assert_array_equal(np.asarray(f.map(301)(pts[None])).ravel(), 0.5)
    np.testing.assert_array_equal(s.evaluate(x=pts), 0.5)
    g = FuzzySystem.from_dict({
        "format": "hybridnav-fis/1", "name": "tail",
        "inputs": [{"name": "x", "range": [-1.0, 1.0], "points": 11,
                    "terms": [{"name": "t", "mf": "gaussmf", "params": [0.0, 0.1]}]}],
        "output": {"name": "y", "range": [0.0, 1.0], "points": 101,
                   "terms": [{"name": "o", "mf": "trimf", "params": [0.0, 0.5, 1.0]}],
                   "defuzz": "centroid", "default": 0.9},
        "rules": [{"if": ["x", "t"], "then": "o"}]})
    h = cs.Function("h", [x], [g.to_casadi(x=x)])
    assert float(h(1.0)) == pytest.approx(float(g.evaluate(x=1.0)), rel=1e-12)
    assert float(g.evaluate(x=1.0)) == pytest.approx(4.299871734759334e-07, rel=1e-12)
