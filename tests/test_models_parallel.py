"""Large batches of the compiled model kernel split over threads (hybridnav.models.parallel):
how a batch is cut, results bit for bit the same whatever the number of threads at batch sizes
around every threshold, a thread that never starts holds nothing up, and the path without a
compiler."""

from __future__ import annotations

import itertools
import os
import subprocess
import sys
import threading

import numpy as np
import pytest

from hybridnav import models
from hybridnav.models import kernel, parallel

# the kernel tests' setup: no kernel switches from the environment (skip without a compiler),
# and states of any kind
from test_models_kernel import _kernel_or_skip, _states  # noqa: F401  (an autouse fixture)


def _threshold_batches(k, steps):
    """Batch sizes where the split changes: one thread / two, one range per thread / more, the
    most ranges per thread; each -1, +0, +1 (and the lanes' odd sizes)."""
    per_robot = steps * k.cost_ns
    edges = [2 * parallel.THREAD_MIN_NS / per_robot, 3 * parallel.PIECE_NS / per_robot,
             2 * parallel.PIECES * parallel.PIECE_NS / per_robot]
    out = {1, 2, 3, 9}
    for e in edges:
        c = int(np.ceil(e))
        out |= {c - 1, c, c + 1}
    return sorted(b for b in out if b >= 1)


@pytest.mark.parametrize("lanes", [1, 2, 4, 8])
def test_pieces_cover_the_batch_in_whole_blocks(lanes):
    for n in (1, 2, 7, 8, 9, 63, 64, 65, 1000, 4097, 10_000):
        for steps, cost in ((1, 300.0), (100, 300.0), (100, 5.0)):
            for want in (1, 2, 3, 16):
                workers, ranges = parallel.pieces(n, steps, cost, lanes, want)
                assert 1 <= workers <= want
                assert ranges[0][0] == 0 and ranges[-1][1] == n
                assert all(a[1] == b[0] for a, b in itertools.pairwise(ranges))
                assert all(lo % lanes == 0 and hi > lo for lo, hi in ranges)
                if workers == 1:
                    assert ranges == [(0, n)]
                else:
                    assert n * steps * cost >= workers * parallel.THREAD_MIN_NS
                    assert workers <= len(ranges) <= workers * parallel.PIECES


def test_below_the_threshold_one_thread():
    k_cost = 250.0
    n = int(2 * parallel.THREAD_MIN_NS // (100 * k_cost))
    assert parallel.pieces(n - 1, 100, k_cost, 2, 2)[0] == 1
    assert parallel.pieces(n + 1, 100, k_cost, 2, 2)[0] == 2
    assert parallel.pieces(10_000, 100, k_cost, 2, 1) == (1, [(0, 10_000)])


@pytest.mark.parametrize("name", ["unicycle", "tractor_trailer"])
def test_threads_change_no_result_around_every_threshold(name):
    m = models.get(name)
    k = m._compiled_kernel()
    steps = 30
    batches = _threshold_batches(k, steps)
    X_all, T_all = _states(m, max(batches), np.random.default_rng(21))
    for n in batches:
        X0, T = X_all[:n], T_all[:n]
        outs = []
        for nthreads in (1, 2, 3, 5):
            traj = np.empty((n, steps + 1, m.nx))
            traj[:, 0] = X0
            before = k.slots()
            kernel.run(k, X0, T, traj, steps, (steps + 1) * m.nx, m.nx, offset=m.nx,
                       nthreads=nthreads)
            assert k.slots() - before == n * steps          # no robot twice, none padded
            outs.append(traj)
        for other in outs[1:]:
            np.testing.assert_array_equal(other, outs[0])
        np.testing.assert_array_equal(m.rollout(X0, T, steps), outs[0])
        np.testing.assert_array_equal(m.step(X0, T), outs[0][:, 1])


def test_step_in_place_over_threads():
    m = models.get("unicycle")
    k = m._compiled_kernel()
    n = int(4 * parallel.THREAD_MIN_NS // k.cost_ns) + 3            # one step: several threads
    assert parallel.pieces(n, 1, k.cost_ns, k.lanes, 2)[0] == 2
    X0, T = _states(m, n, np.random.default_rng(22))
    want = np.empty_like(X0)
    kernel.run(k, X0, T, want, 1, m.nx, m.nx, nthreads=1)
    X = X0.copy()
    kernel.run(k, X, T, X, 1, m.nx, m.nx, nthreads=2)
    np.testing.assert_array_equal(X, want)


def test_a_thread_that_never_starts_holds_nothing_up():
    """The pool's thread busy elsewhere (a shared machine): the calling thread claims every
    range, the pending piece of work is cancelled, the results are the same."""
    m = models.get("tractor_trailer")
    k = m._compiled_kernel()
    steps = 20
    n = 3 * int(parallel.PIECES * parallel.PIECE_NS // (steps * k.cost_ns)) + 1
    X0, T = _states(m, n, np.random.default_rng(23))
    want = m.rollout(X0, T, steps)
    release = threading.Event()
    pool = parallel._pool(1)
    blockers = [pool.submit(release.wait, 60) for _ in range(pool._max_workers)]
    try:
        traj = np.empty((n, steps + 1, m.nx))
        traj[:, 0] = X0
        kernel.run(k, X0, T, traj, steps, (steps + 1) * m.nx, m.nx, offset=m.nx, nthreads=2)
    finally:
        release.set()
        for b in blockers:
            b.result()
    np.testing.assert_array_equal(traj, want)


def test_simd_variant_is_split_in_whole_blocks(monkeypatch):
    """An opt-in SIMD kernel's ranges are whole blocks of lanes: the same empty lanes computed
    (and the same results) on any number of threads."""
    monkeypatch.setenv(kernel.ENV, "auto")
    m = models.get("unicycle")
    k = m._compiled_kernel()
    if k is None or k.variant not in ("sse2", "avx2", "avx512"):
        pytest.skip("no SIMD kernel here")
    steps = 25
    n = int(2 * parallel.PIECES * parallel.PIECE_NS // (steps * k.cost_ns)) + 3
    X0, T = _states(m, n, np.random.default_rng(24))
    outs = []
    for nthreads in (1, 2, 3):
        traj = np.empty((n, steps + 1, m.nx))
        traj[:, 0] = X0
        before = k.slots()
        kernel.run(k, X0, T, traj, steps, (steps + 1) * m.nx, m.nx, offset=m.nx,
                   nthreads=nthreads)
        assert k.slots() - before == -(-n // k.lanes) * k.lanes * steps
        outs.append(traj)
    np.testing.assert_array_equal(outs[1], outs[0])
    np.testing.assert_array_equal(outs[2], outs[0])


def test_without_a_compiler_a_large_batch_runs_on_casadi(tmp_path):
    """No compiler and an empty cache: no kernel, CasADi's virtual machine runs a batch the
    kernel would split over threads; the same results to rounding."""
    code = (
        "import numpy as np\n"
        "from hybridnav import models\n"
        "m = models.get('unicycle')\n"
        "assert m._compiled_kernel() is None and not models.jit_available()\n"
        "X0 = np.load('x0.npy'); T = np.load('t.npy')\n"
        "np.save('traj.npy', m.rollout(X0, T, 20))\n"
    )
    m = models.get("unicycle")
    rng = np.random.default_rng(25)
    n = 1001
    X0 = np.column_stack([rng.uniform(0, 20, (n, 2)), rng.uniform(-1.5, 1.5, n)])
    T = np.tile([45.0, 25.0], (n, 1))
    np.save(tmp_path / "x0.npy", X0)
    np.save(tmp_path / "t.npy", T)
    env = dict(os.environ, CC=str(tmp_path / "no-such-compiler"), HYBRIDNAV_THREADS="2",
               HYBRIDNAV_CACHE_DIR=str(tmp_path / "cache"))
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                          cwd=tmp_path, timeout=300, check=False)
    assert proc.returncode == 0, proc.stderr
    assert parallel.pieces(n, 20, m._compiled_kernel().cost_ns, 2, 2)[0] == 2
    np.testing.assert_allclose(np.load(tmp_path / "traj.npy"), m.rollout(X0, T, 20),
                               rtol=0, atol=1e-12)
