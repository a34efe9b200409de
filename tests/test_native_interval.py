"""The compiled interval evaluation (arithmetic programs) equals the NumPy path bit for bit: the
enclosures, smoothness and continuity of every output, on boxes with zeros of both signs,
subnormals, underflowing products, huge, infinite and NaN ends, with clamps; and programs with
other operations, or switched-off kernels, take the NumPy path."""

from __future__ import annotations

import casadi as cs
import numpy as np
import pytest

from hybridnav import models, native
from hybridnav.analysis.interval import IntervalFunction
from hybridnav.native import interval as native_interval

x = cs.SX.sym("x", 3)
X, Y, Z = x[0], x[1], x[2]

#: arithmetic expressions covering every operation of the kernel (checked below)
EXPRESSIONS = {
    "products": [X * Y, X * Y * Z, (X - Y) * (Y + Z), 3.0 * X * Y - Z, -(X * Y), X],
    "quotients": [X / Y, 1 / X, (X + 1) / (Y * Y + Z), X / (Y - Z) + Y / X],
    "powers": [X * X, (X - Y) ** 2, X ** 2 * Y ** 2 + Z ** 2, -(X ** 2) + 2 * Y],
    "twice": [X + X, 2 * (X * Y), (X + X) / (Y + Y)],
    "underflow": [1e-200 * X * Y, X * Y * 1e-300, 1e300 * X / Y, X / (1e308 * Y)],
    "constants": [X + 1e308 + 1e308, X * 0.0 + Y, cs.SX(np.inf) * X, X - cs.SX(np.inf)],
    "saturations": [cs.fmin(X, Y), cs.fmax(X * Y, 1.0) - cs.fabs(Z), cs.sqrt(X * X + Y * Y),
                    cs.fmin(1, 1 / (0.5 * cs.sqrt(X ** 2 + Y ** 2) + 1e-12)) * X,
                    cs.fmax(cs.fmin(X, 2.0), -2.0) * cs.sqrt(Z), cs.fmax(X, Y), cs.fmin(Y, Z)],
    "jumps": [cs.sign(X) * Y, cs.floor(X) + cs.ceil(Y), cs.if_else(X < Y, X * Y, Z),
              cs.logic_and(X > 0, Y <= Z) + cs.logic_or(X == Y, cs.logic_not(Z != 1.0)),
              cs.if_else(Z >= 0, 1 / Z, 0.0), cs.fabs(X) / cs.if_else(X != 0, X, 1.0),
              # the taken side's flags: a kink in the value, an undefined value not taken
              cs.if_else(X > 0, cs.fabs(Y), Z), cs.if_else(Z > 2, 1 / (Z * Z - 1), Y),
              cs.if_else(X > 0, cs.floor(Y) + cs.fabs(Y), Z)],
    "lbcs-like": [1 / ((X - 1) ** 2 + (Y - 2) ** 2 - 0.25) + 1 / (X ** 2 + Y ** 2 - 1)
                  * ((X - 3) ** 2 + Y ** 2), (X * Y - Z) / ((X - 1) ** 2 + 1e-3)],
}
SPECIAL = np.array([0.0, -0.0, 5e-324, -5e-324, 2.2250738585072014e-308, 1e-300, -1e-300, 1e-160,
                    1.0, -1.0, 0.5, 3.0, 1e150, -1e200, 1e308, -1.7976931348623157e308,
                    np.inf, -np.inf, np.nan])


def _boxes(rng, n: int, special: bool):
    a = rng.normal(0, 3, (n, 3))
    b = rng.normal(0, 3, (n, 3))
    if special:
        for m in (a, b):
            pick = rng.random(m.shape) < 0.35
            m[pick] = rng.choice(SPECIAL, int(pick.sum()))
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    # points (lo = hi), and some reversed boxes: the two paths must agree on them too
    lo[: n // 8] = hi[: n // 8]
    if special:
        lo[n // 8: n // 6], hi[n // 8: n // 6] = hi[n // 8: n // 6].copy(), lo[n // 8: n // 6].copy()
    return lo, hi


def _both(F: IntervalFunction, lo, hi, clamp, monkeypatch):
    compiled = F(lo, hi, clamp, continuity=True)
    with monkeypatch.context() as mp:
        mp.setenv(native.ENV, "0")
        reference = F(lo, hi, clamp, continuity=True)
    return compiled, reference


def _assert_same(compiled, reference):
    for c, r in zip(compiled, reference):
        assert c.dtype == r.dtype and c.shape == r.shape
        np.testing.assert_array_equal(c, r)             # NaN equal to NaN; -0.0 == 0.0
        if c.dtype == float:
            # and the same bits, signed zeros aside
            same = (c == r) | (np.isnan(c) & np.isnan(r))
            assert same.all()


def test_the_expressions_use_every_operation_of_the_kernel():
    used = set()
    for exprs in EXPRESSIONS.values():
        F = IntervalFunction(x, exprs)
        used |= {p[0] for p in F._program}
        assert F._compiled() is not None
    # (CasADi emits ``assign`` for matrix copies, not for these scalar expressions)
    assert set(native_interval.CODES) - {"assign"} <= used


@pytest.mark.skipif(not native.enabled() or native_interval._library() is None,
                    reason="no compiled kernels on this machine")
@pytest.mark.parametrize("special", [False, True])
@pytest.mark.parametrize("group", sorted(EXPRESSIONS))
def test_compiled_enclosures_equal_numpy(group, special, monkeypatch):
    F = IntervalFunction(x, EXPRESSIONS[group])
    rng = np.random.default_rng(abs(hash(group)) % 2 ** 32 + special)
    for n in (1, 7, 600):
        lo, hi = _boxes(rng, n, special)
        _assert_same(*_both(F, lo, hi, None, monkeypatch))


@pytest.mark.skipif(not native.enabled() or native_interval._library() is None,
                    reason="no compiled kernels on this machine")
@pytest.mark.parametrize("group", ["saturations", "jumps"])
def test_ties_of_selections_and_comparisons_equal_numpy(group, monkeypatch):
    """Boxes with small integer ends, so that ends coincide: a selection or comparison decided
    (or not) by a tie takes the same side in both paths."""
    F = IntervalFunction(x, EXPRESSIONS[group])
    rng = np.random.default_rng(11)
    a, b = rng.integers(-2, 3, (2, 3000, 3)).astype(float)
    _assert_same(*_both(F, np.minimum(a, b), np.maximum(a, b), None, monkeypatch))


@pytest.mark.skipif(not native.enabled() or native_interval._library() is None,
                    reason="no compiled kernels on this machine")
def test_clamped_outputs_and_open_bounds_equal_numpy(monkeypatch):
    """As the certificate uses it: constraints g > 0 clamped to [0, inf), then 1 / g."""
    g = (X - 1) ** 2 + (Y + 0.5) ** 2 - 0.25
    F = IntervalFunction(x, [g, 1 / g + X * Y, Y / g, X * X])
    rng = np.random.default_rng(7)
    for clamp in ({0: (0.0, np.inf)}, {0: (0.1, 4.0)}, {3: (0.0, 1.0)}, {0: (0.0, np.inf),
                                                                          3: (-1.0, 2.0)}):
        lo, hi = _boxes(rng, 400, True)
        _assert_same(*_both(F, lo, hi, clamp, monkeypatch))


@pytest.mark.skipif(not native.enabled() or native_interval._library() is None,
                    reason="no compiled kernels on this machine")
def test_the_lbcs_certificate_functions_equal_numpy(monkeypatch):
    """V, Vdot and the constraints of the LbCS closed loop with its obstacles (the certificate
    route's heaviest rational program)."""
    from hybridnav.analysis.lyapunov import lyapunov_functions
    from hybridnav.world import load_scenario

    scen = load_scenario("aco-local-minimum")
    lb = models.LbCS.from_scenario(scen)
    model, v_num, vdot_num, _, _ = lyapunov_functions(lb, None, target=scen.robots[0].goal)
    gx = cs.substitute(model.state_constraints(), model.sym.p, cs.DM(model.p_value()))
    grad = cs.gradient(vdot_num, model.sym.x)
    F = IntervalFunction(model.sym.x, [v_num, vdot_num, gx, grad])
    assert F._compiled() is not None
    ng = int(gx.numel())
    clamp = {2 + k: (0.0, np.inf) for k in range(ng)}
    rng = np.random.default_rng(3)
    c = rng.uniform([-20, -20], [70, 70], (3000, 2))
    w = 10.0 ** rng.uniform(-12, 1.5, (3000, 2))
    lo, hi = c - w, c + w
    lo[:50] = hi[:50]
    _assert_same(*_both(F, lo, hi, clamp, monkeypatch))
    _assert_same(*_both(F, lo, hi, None, monkeypatch))


def test_other_operations_take_the_numpy_path():
    F = IntervalFunction(x, [cs.sin(X) * Y, X * Y])
    assert F._compiled() is None
    lo, hi = np.zeros((4, 3)), np.ones((4, 3))
    out_lo, out_hi, smooth = F(lo, hi)
    assert out_lo.shape == (4, 2) and smooth.all()


def test_switched_off_kernels_give_the_numpy_path(monkeypatch):
    monkeypatch.setenv(native.ENV, "0")
    F = IntervalFunction(x, [X * Y])
    assert native_interval.evaluate(F._compiled(), np.zeros((2, 3)), np.ones((2, 3)), {}) is None
    out_lo, out_hi, _ = F(np.zeros((2, 3)), np.ones((2, 3)))
    assert (out_lo <= 0).all() and (out_hi >= 1).all()


@pytest.mark.skipif(not native.enabled() or native_interval._library() is None,
                    reason="no compiled kernels on this machine")
def test_a_clamped_constant_is_no_open_bound(monkeypatch):
    """The NumPy path marks a slot > 0 (an open bound ``g > 0`` clamped to [0, ...]) only where
    it computes the slot (inputs, operations), never for a constant: a constant 0 clamped to
    [0, inf) stays a divisor holding 0, so x / 0 is undefined on the box, not [0, 0] (review:
    the kernel took the flag for every clamped slot; CasADi folds x / 0 itself, so the program is
    written here by hand)."""
    F = IntervalFunction(x, [X / (Y + 3.0), cs.SX(5.0)])
    F._program = [("input", [0, 0], [0], None, None), ("const", [], [2], 0.0, None),
                  ("div", [0, 2], [4], None, None), ("inv", [2], [5], None, None),
                  ("output", [4], [0, 0], None, None), ("output", [2], [0, 1], None, None),
                  ("output", [5], [0, 2], None, None)]
    F._out_slot, F.n_out, F._kernel = {0: 4, 1: 2, 2: 5}, 3, False
    assert F._compiled() is not None
    lo = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    hi = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    compiled, reference = _both(F, lo, hi, {1: (0.0, np.inf)}, monkeypatch)
    _assert_same(compiled, reference)
    assert np.isneginf(compiled[0][:, [0, 2]]).all() and not compiled[2][:, [0, 2]].any()


@pytest.mark.skipif(not native.enabled() or native_interval._library() is None,
                    reason="no compiled kernels on this machine")
def test_clamps_other_than_real_numbers_as_the_numpy_path(monkeypatch):
    """Per-box clamp arrays broadcast in the NumPy path (the kernel cannot take them), and
    ``None``, strings or complex numbers are errors there (the kernel's float array would take
    ``None`` as NaN and ``"0"`` as 0): such clamps take the NumPy path (review)."""
    g = X * X + Y - 1
    F = IntervalFunction(x, [g, 1 / g + X * Y])
    rng = np.random.default_rng(11)
    lo, hi = _boxes(rng, 6, False)
    clamp = {0: (np.zeros(6), np.full(6, np.inf))}
    _assert_same(*_both(F, lo, hi, clamp, monkeypatch))
    _assert_same(*_both(F, lo, hi, {0: (np.longdouble("0.1"), 2.0)}, monkeypatch))
    for bad in ({0: (None, 1.0)}, {0: ("0", "inf")}):
        with pytest.raises(TypeError):
            F(lo, hi, bad)
    # real scalars of any NumPy type still use the kernel, as the NumPy path would
    for ok in ({0: (0, np.inf)}, {0: (np.float32(0.1), np.int64(4))}, {0: (False, True)}):
        _assert_same(*_both(F, lo, hi, ok, monkeypatch))


def test_a_program_with_an_output_out_of_range_is_not_compiled():
    """The kernel writes outputs by index unchecked: a malformed program (an output row beyond
    n_out, or of a slot never written) takes the NumPy path, which raises (review)."""
    F = IntervalFunction(x, [X * Y])
    prog = list(F._program)
    assert native_interval.program(prog, F.sz_w, F.nx, F.n_out) is not None
    name, ins, outs, const, same = prog[-1]
    assert name == "output"
    for bad in (("output", ins, [outs[0], F.n_out], const, same),
                ("output", [F.sz_w + 5], outs, const, same)):
        assert native_interval.program(prog[:-1] + [bad], F.sz_w, F.nx, F.n_out) is None


_UNARY = ("neg", "twice", "assign", "sq", "sqrt", "fabs", "sign", "floor", "ceil", "not", "inv")
_BINARY_OPS = ("add", "sub", "mul", "div", "fmin", "fmax", "lt", "le", "eq", "ne", "and", "or",
               "if_else_zero")
_CONSTS = (0.0, -0.0, 1.0, -1.0, 0.5, 2.0, 3.0, np.inf, -np.inf, np.nan, 1e308, 5e-324, 1e-300)


def _random_program(rng, n_ops: int):
    """Instructions written by hand (CasADi would fold NaN, -0.0 and infinite constants away):
    every operation of the kernel on inputs, constants and earlier results, and outputs read from
    intermediate slots (so that clamps narrow intermediate values)."""
    prog, slots = [], []
    for i in range(3):
        prog.append(("input", [0, i], [len(slots)], None, None))
        slots.append(len(slots))
    for _ in range(n_ops):
        s = len(slots)
        if rng.random() < 0.1:
            prog.append(("const", [], [s], float(rng.choice(_CONSTS)), None))
        else:
            near = [slots[max(0, s - 1 - int(rng.geometric(0.3)) + 1)], slots[rng.integers(s)]]
            args = [near[int(rng.random() < 0.3)] for _ in range(2)]
            if rng.random() < 0.4:
                prog.append((str(rng.choice(_UNARY)), args[:1], [s], None, None))
            else:
                prog.append((str(rng.choice(_BINARY_OPS)), args, [s], None, None))
        slots.append(s)
    outs = sorted({int(rng.choice(slots[3:])) for _ in range(3)} | {slots[-1]})
    prog += [("output", [sl], [0, k], None, None) for k, sl in enumerate(outs)]
    return prog, len(slots), len(outs), dict(enumerate(outs))


@pytest.mark.skipif(not native.enabled() or native_interval._library() is None,
                    reason="no compiled kernels on this machine")
def test_random_programs_of_every_operation_equal_numpy(monkeypatch):
    """Review (exact operations): random programs over all the kernel's operations, with NaN,
    signed-zero and infinite constants, on boxes with integer ends (ties), special ends, points
    and reversed boxes, clamped intermediate outputs; both flag sets, with and without
    ``continuity``."""
    rng = np.random.default_rng(20261204)
    clamps = [(0.0, np.inf), (0.0, 1.0), (-1.0, 2.0), (1.0, 1.0), (0.5, -0.5), (-0.0, 3.0)]
    for it in range(150):
        prog, sz, n_out, out_slot = _random_program(rng, int(rng.integers(1, 12)))
        F = IntervalFunction(x, [X])
        F._program, F.sz_w, F.n_out, F._out_slot, F._kernel = prog, sz, n_out, out_slot, False
        assert F._compiled() is not None
        clamp = {k: clamps[rng.integers(len(clamps))] for k in range(n_out) if rng.random() < 0.3}
        if it % 3 == 0:
            a, b = rng.integers(-2, 3, (2, 40, 3)).astype(float)
            lo, hi = np.minimum(a, b), np.maximum(a, b)
        else:
            lo, hi = _boxes(rng, 40, it % 3 == 2)
        _assert_same(*_both(F, lo, hi, clamp, monkeypatch))
        compiled = F(lo, hi, clamp)
        with monkeypatch.context() as mp:
            mp.setenv(native.ENV, "0")
            _assert_same(compiled, F(lo, hi, clamp))
