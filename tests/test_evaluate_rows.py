"""``evaluate_rows`` (the analysis tools' evaluation at many states: compiled for large batches,
written through CasADi buffers) gives the virtual machine's values bit for bit, for rational,
trigonometric, saturated and fuzzy closed loops, at NaN and infinite states too; and it runs where
compiling is off."""

from __future__ import annotations

import casadi as cs
import numpy as np
import pytest

from hybridnav import fuzzy, models
from hybridnav.analysis.lyapunov import lyapunov_functions
from hybridnav.models import compile as mc
from hybridnav.world import load_scenario


def _cases():
    scen = load_scenario("aco-local-minimum")
    lb = models.LbCS.from_scenario(scen)
    out = {}
    for name, model, target in (("lbcs", lb, scen.robots[0].goal),
                                ("unicycle", models.get("unicycle"), (1.0, 2.0)),
                                ("tractor-trailer", models.get("tractor_trailer"), (3.0, -1.0))):
        m, v, vdot, _, _ = lyapunov_functions(model, None, target=target)
        out[name] = (cs.Function("v_vdot", [m.sym.x], [v, vdot]), m.nx, ())
    g = lb.state_constraints()
    out["constraints"] = (cs.Function("g", [lb.sym.x, lb.sym.p], [g]), 2, (lb.p_value(),))
    from hybridnav.planners.field.effc_loop import effc_closed_loop

    loop = effc_closed_loop(models.get("unicycle", controller="heading", jit=False),
                            fuzzy.builtin("effc-tuned"), (4.0, 0.0), (2.0, 0.1, 0.5))
    out["effc"] = (cs.Function("rhs", [loop.sym.x], [loop._rhs]), 3, ())
    return out


CASES = _cases()


def _states(rng, n, nx):
    X = rng.uniform(-60, 60, (n, nx))
    X[:5] = 0.0
    X[5:10, 0] = np.nan
    X[10:15, -1] = np.inf
    X[15:20] = rng.uniform(-1e-300, 1e-300, (len(X[15:20]), nx))
    return X


@pytest.mark.parametrize("n", [1, 37, mc.ROWS_JIT_MIN_ROWS + 3])
@pytest.mark.parametrize("name", sorted(CASES))
def test_rows_equal_the_virtual_machine(name, n):
    fn, nx, shared = CASES[name]
    X = _states(np.random.default_rng(n), n, nx)
    got = mc.evaluate_rows(fn, X, *shared)
    ref = fn.map(n)(X.T, *[np.asarray(s)[:, None] for s in shared])
    ref = ref if isinstance(ref, (list, tuple)) else [ref]
    assert len(got) == fn.n_out()
    for g, r in zip(got, ref):
        r = np.asarray(r).reshape(-1, n).T
        assert g.shape == r.shape
        same = (g == r) | (np.isnan(g) & np.isnan(r))
        assert same.all(), (name, np.flatnonzero(~same.all(axis=1))[:5])


def test_rows_without_compiling_and_empty_batches(monkeypatch):
    fn, nx, _ = CASES["lbcs"]
    X = _states(np.random.default_rng(1), mc.ROWS_JIT_MIN_ROWS, nx)
    compiled = mc.evaluate_rows(fn, X)
    monkeypatch.setenv("HYBRIDNAV_JIT", "0")
    assert mc._rows_function(fn) is fn
    vm = mc.evaluate_rows(fn, X)
    for a, b in zip(compiled, vm):
        assert ((a == b) | (np.isnan(a) & np.isnan(b))).all()
    empty = mc.evaluate_rows(fn, np.empty((0, nx)))
    assert [e.shape for e in empty] == [(0, 1), (0, 1)]


@pytest.mark.parametrize("n", [1, 4, mc.ROWS_JIT_MIN_ROWS])
def test_structurally_zero_outputs_are_zeros(n):
    """A buffer holds an output's structural nonzeros only: an identically zero output (an empty
    1 x 1, as CasADi writes a Vdot that vanishes) and a sparse column are written dense."""
    x = cs.SX.sym("x", 2)
    sparse_col = cs.SX(3, 1)
    sparse_col[1] = x[0] * x[1]
    fn = cs.Function("f", [x], [cs.SX(1, 1), sparse_col, x[0] - x[1]])
    X = np.random.default_rng(0).normal(size=(n, 2))
    zero, col, diff = mc.evaluate_rows(fn, X)
    assert zero.shape == (n, 1) and not zero.any()
    assert col.shape == (n, 3) and not col[:, [0, 2]].any()
    np.testing.assert_array_equal(col[:, 1], X[:, 0] * X[:, 1])
    np.testing.assert_array_equal(diff[:, 0], X[:, 0] - X[:, 1])


def test_rows_of_one_function_reuse_its_map():
    fn, nx, shared = CASES["constraints"]
    X = np.ones((3, nx))
    mc.evaluate_rows(fn, X, *shared)
    first = mc._rows_map(fn, 3)
    assert mc._rows_map(fn, 3) is first
    z = cs.SX.sym("z", 2)
    other = cs.Function("g2", [z], [z[0]])
    assert mc._rows_map(other, 3) is not first
