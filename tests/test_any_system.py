"""The analysis of systems that are not hybridnav robot models: python-control, CasADi, expressions
and do-mpc, judged against python-control, sympy and simulation."""

from __future__ import annotations

import warnings

import casadi as cs
import control as ct
import numpy as np
import pytest
import sympy as sp

from hybridnav import models
from hybridnav.analysis import (
    as_system,
    basin,
    basin_share,
    check_lyapunov,
    estimate_roa,
    find_equilibria,
    linearize,
    lyapunov_equation_candidate,
)
from hybridnav.errors import HybridnavError

PARAMS = {"g": 9.81, "l": 1.0, "b": 0.5}
_X = cs.SX.sym("x", 2)


def _pendulum():
    def upd(t, x, u, p):
        return [x[1], -p["g"] / p["l"] * np.sin(x[0]) - p["b"] * x[1] + u[0]]
    return ct.nlsys(upd, None, states=["theta", "omega"], inputs=["tau"],
                    outputs=["theta", "omega"], params=dict(PARAMS), name="pendulum")


def _do_mpc_model(build, setup=True):
    """A continuous do-mpc model with the variables and right-hand sides ``build(m)`` sets."""
    do_mpc = pytest.importorskip("do_mpc")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = do_mpc.model.Model("continuous")
        build(m)
        if setup:
            m.setup()
    return m


def _vdp():
    x = cs.SX.sym("x", 2)
    return cs.Function("vdp", [x], [cs.vertcat(-x[1], x[0] + (x[0] ** 2 - 1) * x[1])])


@pytest.mark.parametrize("theta", [0.0, 0.3, 1e6, -5e5 + 0.1])
def test_linearize_an_nlsys_matches_sympy_and_python_control(theta):
    pend = _pendulum()
    sys = linearize(pend, [theta, 0.2], [0.1])
    assert isinstance(sys, ct.StateSpace) and sys.state_labels == ["theta", "omega"]
    th, om, tau = sp.symbols("theta omega tau")
    f = sp.Matrix([om, -9.81 / 1.0 * sp.sin(th) - 0.5 * om + tau])
    J = f.jacobian([th, om]).subs({th: sp.Float(theta, 30), om: 0.2})
    np.testing.assert_allclose(sys.A, np.array(J, dtype=float), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(sys.B, [[0.0], [1.0]])
    ref = ct.linearize(pend, [theta, 0.2], [0.1])
    np.testing.assert_allclose(sys.A, ref.A, rtol=1e-5, atol=1e-6)   # ct: finite differences


def test_a_tractor_trailer_at_large_coordinates_linearizes_like_at_the_origin():
    tt = models.get("tractor_trailer")
    x0 = np.array([0.0, 0.0, 0.4, 0.1, 0.0])
    near = linearize(tt, x0, target=[5.0, 5.0]).A
    far = linearize(tt, x0 + [5e5, 5e5, 0, 0, 0], target=[5e5 + 5, 5e5 + 5]).A
    np.testing.assert_allclose(far, near, rtol=1e-9, atol=1e-12)


def test_the_pendulum_is_analysed_end_to_end():
    pend = _pendulum()
    V, P = lyapunov_equation_candidate(pend, equilibrium=[0, 0])
    A = np.array([[0, 1], [-9.81, -0.5]])
    np.testing.assert_allclose(A.T @ P + P @ A, -np.eye(2), atol=1e-10)
    eqs = find_equilibria(pend, equilibrium=[0, 0], region={"theta": (-4, 4), "omega": (-2, 2)})
    kinds = {round(float(e.state[0]), 4): e.kind for e in eqs}
    assert kinds == {0.0: "stable", -3.1416: "saddle", 3.1416: "saddle"}
    roa = estimate_roa(pend, V, equilibrium=[0, 0], region={"theta": (-3, 3), "omega": (-6, 6)},
                       confirm=50)
    assert roa.level > 0 and roa.confirmed
    # the level set stays below the saddles' V
    v_saddle = float(cs.Function("v", [as_system(pend).sym.x], [V])(np.array([np.pi, 0])))
    assert v_saddle == pytest.approx(P[0, 0] * np.pi ** 2)
    assert roa.level < v_saddle
    # a candidate built from the system's own symbols, by another trace, is taken by name
    rep = check_lyapunov(pend, V, equilibrium=[0, 0], region={"theta": (-0.3, 0.3),
                                                              "omega": (-0.3, 0.3)})
    assert rep.status == "proved"


def test_reversed_van_der_pol_is_certified_within_two_percent():
    """The textbook test: the Lyapunov-equation candidate's largest level with Vdot < 0 is
    2.3046 (its Vdot touches zero on that level set); the certified level must be within 2 %."""
    vdp = _vdp()
    V, P = lyapunov_equation_candidate(vdp, equilibrium=[0, 0])
    np.testing.assert_allclose(P, [[1.5, -0.5], [-0.5, 1.0]], atol=1e-12)
    roa = estimate_roa(vdp, V, equilibrium=[0, 0], region={"x_0": (-3, 3), "x_1": (-3, 3)},
                       confirm=50)
    assert roa.status == "proved", roa.details
    assert 0.98 * 2.3046 <= roa.level <= 2.3046
    share = basin_share(vdp, V, roa.level, equilibrium=[0, 0],
                        region={"x_0": (-3, 3), "x_1": (-3, 3)}, n=101, horizon=30)
    assert share["certified_in_basin"] == 1.0 and 0.3 < share["share"] < 1.0


def test_reversed_van_der_pol_with_the_default_candidate_does_not_crash():
    rep = estimate_roa(_vdp(), equilibrium=[0, 0], region={"x_0": (-3, 3), "x_1": (-3, 3)},
                       confirm=20)
    # V = |x|^2 / 2: Vdot = (x0^2 - 1) x1^2 >= 0 for |x0| >= 1; nothing above 0.5 is proved
    assert rep.status != "proved" or rep.level <= 0.5


def test_expressions_statespace_and_do_mpc_give_the_same_linearization():
    x, u = cs.SX.sym("x", 2), cs.SX.sym("u")
    rhs = cs.vertcat(x[1], -9.81 * cs.sin(x[0]) - 0.5 * x[1] + u)
    ref = linearize(_pendulum(), [0.2, 0.0], [0.0])
    for obj in [(x, u, rhs), cs.Function("f", [x, u], [rhs])]:
        sys = linearize(obj, [0.2, 0.0], [0.0])
        np.testing.assert_allclose(sys.A, ref.A, rtol=1e-14)
        np.testing.assert_allclose(sys.B, ref.B, rtol=1e-14)
    ss = ct.ss([[0, 1], [-2, -3]], [[0], [1]], np.eye(2), 0)
    np.testing.assert_allclose(linearize(ss, [1.0, 2.0], [0.5]).A, [[0, 1], [-2, -3]])
    def pendulum(m):
        th, om = m.set_variable("_x", "theta"), m.set_variable("_x", "omega")
        tau, b = m.set_variable("_u", "tau"), m.set_variable("_p", "b")
        m.set_rhs("theta", om)
        m.set_rhs("omega", -9.81 * cs.sin(th) - b * om + tau)

    m = _do_mpc_model(pendulum)
    with pytest.raises(HybridnavError, match=r"params.b: the do-mpc model's p variable"):
        linearize(m, [0.2, 0.0], [0.0])
    sys = as_system(m, params={"b": 0.5})
    assert sys.state_names == ("theta", "omega") and sys.input_names == ("tau",)
    np.testing.assert_allclose(linearize(sys, [0.2, 0.0], [0.0]).A, ref.A, rtol=1e-14)


def test_model_to_nlsys_agrees_with_linearize():
    tt = models.get("tractor_trailer")
    x0 = np.array([0.0, 0.0, 0.4, 0.1, 0.0])
    sys = tt.to_nlsys()
    assert sys.ninputs == 2 and sys.nstates == 5
    ref = ct.linearize(sys, x0, [5.0, 5.0])
    ours = linearize(tt, x0, target=[5.0, 5.0])
    np.testing.assert_allclose(ours.A, ref.A, rtol=1e-4, atol=1e-6)
    pm = models.get("point_mass")
    ol = pm.to_nlsys("open_loop")
    assert list(ol.input_labels) == ["vx", "vy"]
    with pytest.raises(HybridnavError, match="kind: expected"):
        pm.to_nlsys("both")


@pytest.mark.parametrize("obj,msg", [
    ("pendulum", "system: expected a hybridnav model"),
    ((cs.SX.sym("x", 2), cs.SX.sym("y", 3)), "rhs: expected 2 entries"),
    ((cs.SX.sym("x", 2), cs.SX.sym("p") * cs.SX.sym("x", 2)), "rhs: depends on symbols"),
])
def test_bad_systems_get_named_errors(obj, msg):
    with pytest.raises(HybridnavError, match=msg):
        as_system(obj)


def test_an_untraceable_nlsys_and_a_missing_equilibrium_are_refused_clearly():
    def upd(t, x, u, p):
        return np.array([float(x[0]) ** 2, 0.0])          # float() of a symbol
    bad = ct.nlsys(upd, None, states=2, inputs=0)
    with pytest.raises(HybridnavError, match="cannot be traced with CasADi symbols"):
        linearize(bad, [0, 0])
    with pytest.raises(HybridnavError, match="equilibrium: required"):
        check_lyapunov(_vdp(), region={"x_0": (-1, 1), "x_1": (-1, 1)})
    with pytest.raises(HybridnavError, match="equilibrium: expected 2 finite numbers"):
        check_lyapunov(_vdp(), equilibrium=[0, 0, 0], region={"x_0": (-1, 1), "x_1": (-1, 1)})


def test_discrete_time_one_state_and_default_named_systems():
    d = ct.nlsys(lambda t, x, u, p: [-2.0 * x[0]], states=["x"], inputs=0, dt=0.1, name="d")
    with pytest.raises(HybridnavError, match="expected a continuous-time system"):
        check_lyapunov(d, equilibrium=[0.0], region={"x": (-1, 1)})
    x = cs.SX.sym("x")
    lin = linearize((x, -x), [0.0])
    assert lin.A.shape == (1, 1) and lin.B.shape == (1, 0)
    pend = ct.nlsys(lambda t, x, u, p: [x[1], -np.sin(x[0]) - x[1]], states=2, inputs=0)
    eqs = find_equilibria(pend, equilibrium=[0, 0], region={"x[0]": (-1, 1), "x[1]": (-1, 1)}
                          if "x[0]" in as_system(pend).state_names else
                          dict.fromkeys(as_system(pend).state_names, (-1, 1)))
    assert eqs[0].is_target and eqs[0].kind == "stable"


def test_a_small_kink_is_not_linearized():
    x = cs.SX.sym("x", 2)
    f = cs.vertcat(1e-4 * cs.fabs(x[0]) - 0.5e-4 * x[0], -x[1])
    with pytest.raises(HybridnavError, match="not differentiable"):
        linearize((x, f), [0, 0])


@pytest.mark.parametrize("call,msg", [
    (lambda v: basin(v, equilibrium=[0, 0], region={"x_0": (-1, 1), "x_1": (-1, 1)},
                     fixed={"zz": 1}), "fixed.zz: not a state"),
    (lambda v: basin(v, equilibrium=[0, 0], region={"x_0": (-1, 1), "x_1": (-1, 1)}, n="a"),
     "n: expected an integer"),
    (lambda v: find_equilibria(v, equilibrium=[0, 0], region={"x_0": (-1, 1), "x_1": (-1, 1)},
                               starts="a"), "starts: expected a positive integer"),
    (lambda v: lyapunov_equation_candidate(v, equilibrium=[0, 0], Q="a"), "Q: expected"),
    (lambda v: as_system((_X, -_X), dt="a"), "dt: expected"),
])
def test_bad_arguments_get_named_errors(call, msg):
    with pytest.raises(HybridnavError, match=msg):
        call(_vdp())


def test_do_mpc_models_not_set_up_or_without_parameter_values_are_refused():
    def decay(m):
        th, k = m.set_variable("_x", "theta"), m.set_variable("_p", "k")
        m.set_rhs("theta", -k * th)

    m = _do_mpc_model(decay, setup=False)
    with pytest.raises(HybridnavError, match="not set up"):
        as_system(m)
    m.setup()
    for bad in ("a", [], float("nan")):
        with pytest.raises(HybridnavError, match="params.k: expected finite numbers"):
            as_system(m, params={"k": bad})
    assert linearize(as_system(m, params={"k": 2.0}), [0.0], []).A[0, 0] == -2.0


def test_a_changed_python_control_system_is_traced_again():
    pend = _pendulum()
    a = linearize(pend, [0.0, 0.0], [0.0]).A
    pend.params["b"] = 2.0                    # the user changes a parameter afterwards
    b = linearize(pend, [0.0, 0.0], [0.0]).A
    assert a[1, 1] == -0.5 and b[1, 1] == -2.0
    assert as_system(pend) is as_system(pend)    # unchanged: the same System (its symbols)
