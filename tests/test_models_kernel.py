"""The compiled rollout kernel (hybridnav.models.kernel): bit for bit CasADi's compiled path, any
batch size without padding, step repeated = rollout = each robot alone, threads, the opt-in SIMD
variants."""

from __future__ import annotations

import math
import multiprocessing
from concurrent.futures import ProcessPoolExecutor

import casadi as cs
import numpy as np
import pytest

from hybridnav import models
from hybridnav.analysis.system import System
from hybridnav.models import kernel

CASES = [("point_mass", {}), ("unicycle", {}), ("unicycle", {"controller": "heading"}),
         ("unicycle", {"wheel_max": 0.6}), ("tractor_trailer", {}),
         ("tractor_trailer", {"xi_law": "paper"}), ("lbcs", {})]


@pytest.fixture(autouse=True)
def _kernel_or_skip(monkeypatch):
    for var in (kernel.ENV, kernel.THREADS_ENV, "HYBRIDNAV_NATIVE", "HYBRIDNAV_JIT"):
        monkeypatch.delenv(var, raising=False)
    if models.get("point_mass")._compiled_kernel() is None:
        pytest.skip("no compiled kernel here (no C compiler)")


def _states(m, n, rng):
    """Anything: positions within 30 m, angles and xi in (-4, 4) (jackknifed trailers too)."""
    X0 = np.column_stack([rng.uniform(-30, 30, (n, 2)), rng.uniform(-4, 4, (n, m.nx - 2))])
    return X0, rng.uniform(-30, 30, (n, m.target_size))


def _casadi_path(monkeypatch, name, opts):
    """The same model on CasADi's JIT-compiled map (the path before the kernel)."""
    if not models.jit_available():
        pytest.skip("CasADi cannot JIT-compile here")
    monkeypatch.setenv("HYBRIDNAV_NATIVE", "0")
    ref = models.get(name, **opts)
    assert ref._compiled_kernel() is None
    monkeypatch.delenv("HYBRIDNAV_NATIVE")
    return ref


@pytest.mark.parametrize("name, opts", CASES)
def test_kernel_is_casadis_compiled_path_bit_for_bit(monkeypatch, name, opts):
    m = models.get(name, **opts)
    k = m._compiled_kernel()
    assert k.exact
    ref_model = _casadi_path(monkeypatch, name, opts)
    X0, T = _states(m, 263, np.random.default_rng(11))          # CasADi: 256 + 7 robots
    got = m.rollout(X0, T, 40)
    ref = ref_model.rollout(X0, T, 40)
    np.testing.assert_array_equal(got, ref)
    np.testing.assert_array_equal(m.step(X0, T), ref[:, 1])


@pytest.mark.parametrize("name", ["tractor_trailer", "unicycle", "point_mass"])
def test_rollout_is_repeated_step_and_each_robot_alone_at_odd_batch_sizes(name):
    m = models.get(name)
    k = m._compiled_kernel()
    X_all, T_all = _states(m, 10_000, np.random.default_rng(12))
    steps = 12
    for n in (1, 9, 4097, 10_000):
        X0, T = X_all[:n], T_all[:n]
        before = k.slots()
        traj = m.rollout(X0, T, steps)
        assert k.slots() - before == n * steps           # no padding slot computed
        X = X0.copy()
        for j in range(steps):
            X = m.step(X, T)
            np.testing.assert_array_equal(X, traj[:, j + 1])
        for i in sorted({0, 1 % n, n // 2, n - 2 if n > 1 else 0, n - 1}):
            np.testing.assert_array_equal(traj[i], m.rollout(X0[i:i + 1], T[i:i + 1], steps)[0])


def test_threads_change_no_result_and_no_robot_count(monkeypatch):
    m = models.get("tractor_trailer")
    k = m._compiled_kernel()
    X0, T = _states(m, 5001, np.random.default_rng(13))
    steps = 20
    outs = []
    for nthreads in (1, 2, 3):
        traj = np.empty((len(X0), steps + 1, m.nx))
        traj[:, 0] = X0
        before = k.slots()
        kernel.run(k, X0, T, traj, steps, (steps + 1) * m.nx, m.nx, offset=m.nx,
                   nthreads=nthreads)
        assert k.slots() - before == len(X0) * steps
        outs.append(traj)
    np.testing.assert_array_equal(outs[0], outs[1])
    np.testing.assert_array_equal(outs[0], outs[2])
    monkeypatch.setenv(kernel.THREADS_ENV, "2")
    assert kernel.threads() == 2
    np.testing.assert_array_equal(m.rollout(X0, T, steps), outs[0])
    np.testing.assert_array_equal(m.step(X0, T), outs[0][:, 1])
    monkeypatch.setenv(kernel.THREADS_ENV, "many")
    assert kernel.threads() == 1


def test_a_pool_worker_runs_batches_on_one_thread():
    """The tuner's and compare's worker processes already fill the CPUs: no threads there."""
    ctx = multiprocessing.get_context("fork")
    with ProcessPoolExecutor(max_workers=1, mp_context=ctx) as pool:
        assert pool.submit(kernel.threads).result() == 1


def test_step_writes_into_out_and_in_place():
    m = models.get("unicycle")
    X0, T = _states(m, 11, np.random.default_rng(14))
    want = m.step(X0, T)
    X = X0.copy()
    assert m.step(X, T, out=X) is X
    np.testing.assert_array_equal(X, want)
    out = np.zeros((11, 3))
    assert m.step(X0, T, out=out) is out
    np.testing.assert_array_equal(out, want)
    wide = np.zeros((11, 6))
    m.step(X0, T, out=wide[:, ::2])                      # not contiguous: written through a copy
    np.testing.assert_array_equal(wide[:, ::2], want)
    Xf = np.asfortranarray(X0)
    np.testing.assert_array_equal(m.step(Xf, T), want)


def _every_operation_system():
    x = cs.SX.sym("x", 3)
    a, b, c = x[0], x[1], x[2]
    rhs = cs.vertcat(
        cs.fmax(a, b) + cs.fmin(b, -a) + cs.sign(c) + cs.fabs(a) * cs.if_else(
            b > 0, cs.exp(-b ** 2), cs.log(1 + a ** 2)) + (a <= c) - (a == b) + cs.logic_not(c),
        cs.sin(a) * cs.cos(b) + cs.tanh(c) + cs.atan2(b, a) + cs.floor(c) + cs.ceil(a)
        + cs.tan(0.1 * b) + cs.atan(c) + cs.asin(0.5 * cs.sin(a)) + cs.acos(0.5 * cs.cos(b)),
        cs.sqrt(a ** 2 + 1) + b ** 3 + cs.power(cs.fabs(a) + 1, 0.3 * cs.sin(b)) + 1 / (2 + c ** 2)
        + cs.sinh(0.1 * a) - cs.cosh(0.1 * b) + cs.fmod(a, 1.3) + cs.logic_and(a > 0, b < 0)
        + cs.logic_or(a > 1, c < -1) + cs.erf(c) + cs.log1p(a ** 2) + cs.expm1(-b ** 2)
        + cs.hypot(a, c) + cs.copysign(1.0, b) + cs.asinh(a) + cs.atanh(0.5 * cs.tanh(b)),
    )
    return System(x, None, rhs, dt=0.05, name="every_op")


def test_kernel_emits_every_operation_bit_for_bit(monkeypatch):
    """The operations CasADi has beyond the models' (exp, pow, comparisons, if_else, floor, ...),
    at ordinary inputs and at ties, signed zeros, infinities and NaN."""
    sysm = _every_operation_system()
    assert sysm._compiled_kernel() is not None and sysm._compiled_kernel().exact
    rng = np.random.default_rng(15)
    X0 = rng.uniform(-3, 3, (301, 3))
    special = np.array([0.0, -0.0, 1.0, -1.0, np.inf, -np.inf, np.nan, 1e-310, 2.0])
    grid = np.array(np.meshgrid(special, special, special)).reshape(3, -1).T
    T = np.zeros((301, 3))
    monkeypatch.setenv("HYBRIDNAV_NATIVE", "0")
    ref_sys = _every_operation_system()
    assert ref_sys._compiled_kernel() is None
    if not models.jit_available():
        pytest.skip("CasADi cannot JIT-compile here")
    np.testing.assert_array_equal(sysm.rollout(X0, T, 20), ref_sys.rollout(X0, T, 20))
    Tg = np.zeros_like(grid)
    with np.errstate(all="ignore"):
        np.testing.assert_array_equal(sysm.step(grid, Tg), ref_sys.step(grid, Tg))


def test_an_operation_the_kernel_lacks_leaves_casadis_path():
    x = cs.SX.sym("x", 1)
    sysm = System(x, None, -x + 0.1 * cs.remainder(x, 0.25), name="remainder")
    assert sysm._compiled_kernel() is None
    traj = sysm.rollout(np.array([[0.3]]), np.zeros((1, 1)), 5)
    assert np.isfinite(traj).all() and traj[0, -1, 0] < 0.3


def test_jit_false_and_native_off_use_casadi(monkeypatch):
    assert models.get("unicycle", jit=False)._compiled_kernel() is None
    monkeypatch.setenv("HYBRIDNAV_JIT", "0")
    assert models.get("unicycle")._compiled_kernel() is None
    monkeypatch.delenv("HYBRIDNAV_JIT")
    monkeypatch.setenv("HYBRIDNAV_NATIVE", "off")
    assert models.get("unicycle")._compiled_kernel() is None


def _simd_or_skip(monkeypatch, name, **opts):
    monkeypatch.setenv(kernel.ENV, "auto")
    m = models.get(name, **opts)
    k = m._compiled_kernel()
    if k is None or k.variant not in ("sse2", "avx2", "avx512"):
        pytest.skip("no SIMD kernel here (x86-64 with glibc's libmvec >= 2.35)")
    return m, k


def _converging_starts(m, n, rng):
    """Starts 2-20 m from the target (45, 25), headings within 90 degrees of it."""
    target = np.array([45.0, 25.0])
    starts = target + rng.uniform(2, 20, n)[:, None] * np.column_stack(
        [np.cos(a := rng.uniform(-math.pi, math.pi, n)), np.sin(a)])
    heading = np.arctan2(target[1] - starts[:, 1], target[0] - starts[:, 0]) + rng.uniform(
        -math.pi / 2, math.pi / 2, n)
    X0 = np.zeros((n, m.nx))
    X0[:, :2] = starts
    X0[:, 2] = heading
    if m.nx == 5:
        X0[:, 3] = heading
    return m.retarget(X0, np.tile(target, (n, 1))), np.tile(target, (n, 1))


@pytest.mark.parametrize("name", ["unicycle", "tractor_trailer"])
def test_simd_opt_in_is_consistent_and_close_on_converging_runs(monkeypatch, name):
    """HYBRIDNAV_SIMD=auto: libmvec's functions (not bit for bit glibc's scalar ones). Every robot
    goes through the same lanes' code: step = rollout, batch = each robot alone, bit for bit;
    empty lanes of the last block are computed (and counted); trajectories that converge stay
    within 1e-12 of the exact path over 100 steps."""
    m, k = _simd_or_skip(monkeypatch, name)
    assert not k.exact
    X0, T = _converging_starts(m, 1001, np.random.default_rng(16))
    before = k.slots()
    traj = m.rollout(X0, T, 100)
    assert k.slots() - before == -(-1001 // k.lanes) * k.lanes * 100
    X = X0.copy()
    for j in range(100):
        X = m.step(X, T)
    np.testing.assert_array_equal(X, traj[:, -1])
    for i in (0, 1000):
        np.testing.assert_array_equal(traj[i], m.rollout(X0[i:i + 1], T[i:i + 1], 100)[0])
    monkeypatch.delenv(kernel.ENV)
    exact = models.get(name)
    assert exact._compiled_kernel().exact
    np.testing.assert_allclose(traj, exact.rollout(X0, T, 100), rtol=0, atol=1e-12)


def test_models_without_libmvec_functions_get_the_widest_variant_exactly(monkeypatch):
    m = models.get("point_mass")
    k = m._compiled_kernel()
    assert k.exact
    if k.variant == "exact":
        pytest.skip("no SIMD kernel here")
    ref_model = _casadi_path(monkeypatch, "point_mass", {})
    X0, T = _states(m, 4097, np.random.default_rng(17))
    before = k.slots()
    got = m.rollout(X0, T, 30)
    assert k.slots() - before == 4097 * 30                  # the odd robot runs alone
    np.testing.assert_array_equal(got, ref_model.rollout(X0, T, 30))
