"""Review of ``evaluate_rows``: sparse outputs, fmin/fmax at signed zeros, functions whose
generated code needs a symbol no library has, Callbacks, and inputs of the wrong size (each
against the virtual machine call it replaced: ``np.asarray(fn.map(N)(X.T, ...))``)."""

from __future__ import annotations

import itertools
import os
import subprocess
import sys

import casadi as cs
import numpy as np
import pytest

from hybridnav.models import compile as mc

BIG = mc.ROWS_JIT_MIN_ROWS + 1


def _vm(fn, X, *shared):
    ref = fn.map(len(X))(X.T, *[np.asarray(s, dtype=float).reshape(-1, 1) for s in shared])
    ref = ref if isinstance(ref, (list, tuple)) else [ref]
    return [np.asarray(r) for r in ref]


def _bits(a):
    return np.ascontiguousarray(a, dtype=float).view(np.int64)


@pytest.mark.parametrize("n", [3, BIG])
def test_sparse_outputs_are_read_as_the_virtual_machine_gives_them(n):
    x = cs.SX.sym("x", 2)
    g = cs.SX(3, 1)                      # entry 1 a structural zero
    g[0], g[2] = x[0], 2 * x[1]
    fn = cs.Function("sparse_out", [x], [g, cs.SX(1, 1)])
    X = np.arange(2.0 * n).reshape(n, 2) + 1
    got = mc.evaluate_rows(fn, X)
    ref = _vm(fn, X)
    np.testing.assert_array_equal(got[0], ref[0].T)
    np.testing.assert_array_equal(got[1], np.zeros((n, 1)))      # not uninitialized memory


def test_fmin_fmax_at_signed_zeros_as_the_virtual_machine():
    x = cs.SX.sym("x", 2)
    fn = cs.Function("min_max_zeros", [x], [cs.fmin(x[0], x[1]), cs.fmax(x[0], x[1]),
                                            cs.fmax(x[0], 0), 1 / cs.fmin(x[0], 0)])
    vals = [0.0, -0.0, 1.0, -1.0, np.inf, -np.inf, np.nan]
    pairs = np.array(list(itertools.product(vals, vals)))
    X = np.resize(pairs, (BIG, 2))
    got = mc.evaluate_rows(fn, X)
    if not mc.jit_available():
        pytest.skip("no compiler")
    for g, r in zip(got, _vm(fn, X)):
        r = r.reshape(-1, BIG).T
        same = (_bits(g) == _bits(r)) | (np.isnan(g) & np.isnan(r))
        assert same.all(), X[~same.ravel()][:4]


def test_a_symbol_no_library_defines_falls_back_instead_of_killing_the_process(tmp_path):
    # CasADi generates a call to erfinv, which glibc does not have: the library linked, and
    # the process died at the first call ("symbol lookup error")
    code = (
        "import casadi as cs, numpy as np\n"
        "from hybridnav.models import compile as mc\n"
        "x = cs.SX.sym('x')\n"
        "fn = cs.Function('uses_erfinv', [x], [cs.erfinv(x)])\n"
        f"X = np.linspace(-0.9, 0.9, {BIG})[:, None]\n"
        "got = mc.evaluate_rows(fn, X)[0].ravel()\n"
        "ref = np.asarray(fn.map(len(X))(X.T)).ravel()\n"
        "assert np.array_equal(got, ref)\n"
        "print('ok')\n")
    env = {**os.environ, "HYBRIDNAV_CACHE_DIR": str(tmp_path)}
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                          timeout=300)
    assert proc.returncode == 0 and proc.stdout.strip() == "ok", proc.stderr[-2000:]


class _Twice(cs.Callback):
    def __init__(self):
        cs.Callback.__init__(self)
        self.construct("twice", {})

    def get_n_in(self):
        return 1

    def get_n_out(self):
        return 1

    def get_sparsity_in(self, i):
        return cs.Sparsity.dense(2, 1)

    def get_sparsity_out(self, i):
        return cs.Sparsity.dense(2, 1)

    def eval(self, arg):
        return [2 * arg[0]]


def test_a_callback_is_evaluated_in_large_batches_too():
    fn = _Twice()
    X = np.random.default_rng(0).standard_normal((BIG, 2))
    (got,) = mc.evaluate_rows(fn, X)       # was: n_instructions not defined for Callback
    np.testing.assert_array_equal(got, 2 * X)


def test_inputs_of_the_wrong_size_are_refused_not_misread():
    x, p = cs.SX.sym("x", 2), cs.SX.sym("p", 2)
    fn = cs.Function("g", [x, p], [x[0] * p[0] + x[1] * p[1]])
    X = np.arange(15.0).reshape(5, 3)
    with pytest.raises(ValueError, match=r"g: expected states of shape \(N, 2\), got \(5, 3\)"):
        mc.evaluate_rows(fn, X, [1.0, 1.0])         # read as 7.5 rows of 2 before
    with pytest.raises(ValueError, match="g: expected 1 shared inputs, got 0"):
        mc.evaluate_rows(fn, X[:, :2])              # p read as zeros before
    with pytest.raises(ValueError, match="g: input i1: expected 2 values, got 3"):
        mc.evaluate_rows(fn, X[:, :2], [1.0, 1.0, 1.0])   # silently cut before
    got = mc.evaluate_rows(fn, X[:, :2], np.array([[1.0], [2.0]]))[0]
    np.testing.assert_array_equal(got.ravel(), _vm(fn, X[:, :2], [1.0, 2.0])[0].ravel())
