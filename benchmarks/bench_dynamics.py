"""Tractor-trailer closed loop, 50 robots x 100 steps: hybridnav vs NumPy RK4 vs solve_ivp loop;
then ns per robot-step of hybridnav's rollout vs a hand-written NumPy RK4 over batch sizes.

Part 1 prints times measured in this one run and their ratios (targets: hybridnav >= 3x faster
than the hand-written NumPy vectorized RK4, >= 100x faster than a Python loop of ``solve_ivp`` per
robot). Part 2 prints, for the tractor-trailer and the unicycle at batches 1 ... 10,000 (100
steps), ns per robot-step of the NumPy RK4 and of ``Model.rollout`` as it runs by default (exact
scalar math, threads per ``HYBRIDNAV_THREADS``), their ratio against the target (>= 1.5x), and for
information the rollout on one thread and with the opt-in SIMD math (``HYBRIDNAV_SIMD=auto``,
results differ by rounding: the largest difference from the default is printed). Timings are
best-of, interleaved, so load from other processes hits every column alike.
Run: ``python benchmarks/bench_dynamics.py [--robots 50] [--steps 100] [--repeat 20]
[--batches 1,10,50,1000,4096,10000] [--budget 0.6]``.
"""

from __future__ import annotations

import argparse
import math
import os
import time

import numpy as np
from scipy.integrate import solve_ivp

from hybridnav import models


def numpy_rhs(X, T, q):
    """The same closed loop (filter xi law), vectorized by hand."""
    x, y, th0, th1, xi = X.T
    dx, dy = T[:, 0] - x, T[:, 1] - y
    v = q["alpha"] * np.hypot(dx, dy)
    gap = np.abs(th0 - th1)
    beta = np.maximum(0.0, 0.5 - np.cos(gap)) * np.sign(th1 - th0)
    tphi = np.tan(7.0 / 9.0 * np.arctan(xi + beta / np.cos(gap)))
    e = np.arctan2(dy, dx) - th0
    e = np.arctan2(np.sin(e), np.cos(e))
    return np.stack([
        v * np.cos(th0) - v / 2 * tphi * np.sin(th0),
        v * np.sin(th0) + v / 2 * tphi * np.cos(th0),
        v / q["L"] * tphi,
        v / q["Lt"] * (np.sin(th0 - th1) - q["c"] / q["L"] * tphi * np.cos(th0 - th1)),
        q["k_xi"] * (e - xi),
    ], axis=1)


def numpy_unicycle_rhs(X, T, q):
    """The unicycle's go-to-point closed loop, vectorized by hand (no wheel limit by default)."""
    x, y, th = X.T
    dx, dy = T[:, 0] - x, T[:, 1] - y
    e = np.arctan2(dy, dx) - th
    e = np.arctan2(np.sin(e), np.cos(e))
    v = q["k_rho"] * np.hypot(dx, dy) * np.cos(e)
    omega = q["k_alpha"] * e
    if np.isfinite(q["wheel_max"]):
        half = omega * q["L"] / 2
        scale = np.maximum(1.0, np.maximum(np.abs(v - half), np.abs(v + half)) / q["wheel_max"])
        v, omega = v / scale, omega / scale
    return np.stack([v * np.cos(th), v * np.sin(th), omega], axis=1)


def numpy_rollout(X0, T, steps, h, q, rhs=numpy_rhs):
    out = np.empty((len(X0), steps + 1, X0.shape[1]))
    out[:, 0] = X = X0
    for k in range(steps):
        k1 = rhs(X, T, q)
        k2 = rhs(X + h / 2 * k1, T, q)
        k3 = rhs(X + h / 2 * k2, T, q)
        k4 = rhs(X + h * k3, T, q)
        X = X + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        out[:, k + 1] = X
    return out


def best_of(fn, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", type=int, default=50)
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--batches", default="1,10,50,1000,4096,10000",
                    help="batch sizes of part 2 (comma-separated; empty: skip part 2)")
    ap.add_argument("--budget", type=float, default=0.6,
                    help="part 2: about this many seconds of repeats per batch and column")
    args = ap.parse_args()
    n, steps = args.robots, args.steps
    rng = np.random.default_rng(0)
    target = np.array([45.0, 25.0])
    T = np.tile(target, (n, 1))

    print(f"tractor-trailer closed loop, {n} robots x {steps} steps of dt = 0.1 s, best of "
          f"{args.repeat}; JIT compiler available: {models.jit_available()}")
    results = {}
    for label, jit in (("hybridnav (JIT)", True), ("hybridnav (VM)", False)):
        if jit and not models.jit_available():
            continue
        m = models.get("tractor_trailer", jit=jit)
        X0 = np.array([m.initial_state(rng.uniform(0, 20, 2), target,
                                       {"theta0": a, "theta1": a})
                       for a in rng.uniform(-math.pi / 2, math.pi / 2, n)])
        t0 = time.perf_counter()
        ours = m.rollout(X0, T, steps)
        build = time.perf_counter() - t0
        results[label] = best_of(lambda: m.rollout(X0, T, steps), args.repeat)
        print(f"  {label:24s} {results[label] * 1e3:9.3f} ms   (first call incl. build "
              f"{build * 1e3:.0f} ms)")
    q = m.values
    ref = numpy_rollout(X0, T, steps, m.dt, q)
    results["numpy"] = best_of(lambda: numpy_rollout(X0, T, steps, m.dt, q), args.repeat)
    print(f"  {'NumPy vectorized RK4':24s} {results['numpy'] * 1e3:9.3f} ms   "
          f"(max |difference| {np.abs(ref - ours).max():.1e})")
    rhs = m.numeric_closed_loop()
    t_eval = np.arange(steps + 1) * m.dt

    def ivp_loop():
        for i in range(n):
            solve_ivp(lambda t, x: rhs(x, target), (0, t_eval[-1]), X0[i], t_eval=t_eval,
                      rtol=1e-8, atol=1e-8)

    results["solve_ivp"] = best_of(ivp_loop, max(1, args.repeat // 10))
    print(f"  {'solve_ivp loop (RK45)':24s} {results['solve_ivp'] * 1e3:9.3f} ms")
    best = min(v for k, v in results.items() if k.startswith("hybridnav"))
    print(f"ratio NumPy / hybridnav:     {results['numpy'] / best:8.1f}x   (target >= 3x)")
    print(f"ratio solve_ivp / hybridnav: {results['solve_ivp'] / best:8.1f}x   (target >= 100x)")
    if "hybridnav (VM)" in results:
        print(f"without a compiler (VM):     {results['numpy'] / results['hybridnav (VM)']:8.1f}x "
              f"vs NumPy, {results['solve_ivp'] / results['hybridnav (VM)']:.1f}x vs solve_ivp")
    batches = [int(b) for b in args.batches.split(",") if b.strip()]
    if batches:
        print()
        batch_table(batches, args.steps, args.budget)


def _states(m, n, rng):
    """Starts 0-20 m from the origin, headings within 90 degrees of the bearing to the target
    (45, 25), controller states set for it (as planners start robots)."""
    target = np.array([45.0, 25.0])
    starts = rng.uniform(0, 20, (n, 2))
    bearing = np.arctan2(target[1] - starts[:, 1], target[0] - starts[:, 0])
    heading = bearing + rng.uniform(-math.pi / 2, math.pi / 2, n)
    names = m.state_names[2:3] if m.name == "unicycle" else m.state_names[2:4]
    X0 = np.zeros((n, m.nx))
    X0[:, :2] = starts
    for name in names:
        X0[:, m.state_names.index(name)] = heading
    return m.retarget(X0, np.tile(target, (n, 1))), np.tile(target, (n, 1))


def _casadi_map_model(name):
    """The model on CasADi's JIT-compiled map (the path without the kernel; no padding now)."""
    saved = os.environ.get("HYBRIDNAV_NATIVE")
    os.environ["HYBRIDNAV_NATIVE"] = "0"
    try:
        m = models.get(name)
        m._compiled_kernel()                       # chosen now, while the kernel is off
    finally:
        if saved is None:
            del os.environ["HYBRIDNAV_NATIVE"]
        else:
            os.environ["HYBRIDNAV_NATIVE"] = saved
    return m


def _rollout_with(m, k, threads, X, T, steps):
    """``m.rollout`` through kernel ``k`` on ``threads`` threads (None: the default)."""
    from hybridnav.models import kernel

    traj = np.empty((len(X), steps + 1, m.nx))
    traj[:, 0] = X
    kernel.run(k, X, T, traj, steps, (steps + 1) * m.nx, m.nx, offset=m.nx, nthreads=threads)
    return traj


def _time_batch(cols, n, steps, budget):
    """ns per robot-step of each column, best of interleaved repeats (about ``budget`` s each)."""
    once = {c: best_of(f, 1) for c, f in cols.items()}          # builds, warms up
    once = {c: best_of(f, 1) for c, f in cols.items()}
    repeat = max(2, min(200, int(budget / max(once.values()))))
    best = dict(once)
    for _ in range(repeat):
        for c, f in cols.items():
            best[c] = min(best[c], best_of(f, 1))
    return {c: v / (n * steps) * 1e9 for c, v in best.items()}


def batch_table(batches, steps, budget):
    """ns per robot-step, NumPy RK4 vs hybridnav, per batch size (part 2)."""
    from functools import partial

    from hybridnav.models import kernel

    print(f"part 2: ns per robot-step (wall clock), {steps} steps of dt = 0.1 s, best of "
          f"interleaved repeats; threads = {kernel.threads()} (HYBRIDNAV_THREADS), CPUs usable "
          f"{len(os.sched_getaffinity(0))}, load average {os.getloadavg()[0]:.2f} at the start")
    print("  hybridnav = Model.rollout as it runs by default; 1 thread = the same kernel on one "
          "thread;\n  CasADi map = the path without the kernel (HYBRIDNAV_NATIVE=0); SIMD = "
          "opt-in HYBRIDNAV_SIMD=auto,\n  max|diff| = its largest difference from the default "
          "(which equals CasADi map bit for bit)")
    rhs_of = {"tractor_trailer": numpy_rhs, "unicycle": numpy_unicycle_rhs}
    rng = np.random.default_rng(1)
    met = total = 0
    for name in ("tractor_trailer", "unicycle"):
        m = models.get(name)
        k_exact = m._compiled_kernel()
        k_simd = kernel.get(m, "auto")
        if k_simd is not None and k_simd.exact:
            k_simd = None
        m_map = _casadi_map_model(name)
        print(f"{name}: default kernel {k_exact.variant if k_exact else 'none (CasADi map)'}, "
              f"SIMD opt-in {k_simd.variant if k_simd else 'unavailable'}")
        print(f"  {'batch':>6s} {'NumPy':>8s} {'hybridnav':>9s} {'ratio':>6s} {'>=1.5x':>6s} "
              f"{'1 thread':>8s} {'ratio':>6s} {'CasADi map':>10s} {'ratio':>6s} "
              f"{'SIMD':>6s} {'ratio':>6s} {'max|diff|':>9s}")
        X_all, T_all = _states(m, max(batches), rng)
        for n in batches:
            X0, T = np.ascontiguousarray(X_all[:n]), np.ascontiguousarray(T_all[:n])
            cols = {"numpy": partial(numpy_rollout, X0, T, steps, m.dt, m.values, rhs_of[name]),
                    "default": partial(m.rollout, X0, T, steps),
                    "map": partial(m_map.rollout, X0, T, steps)}
            if k_exact is not None:
                cols["1 thread"] = partial(_rollout_with, m, k_exact, 1, X0, T, steps)
            if k_simd is not None:
                cols["simd"] = partial(_rollout_with, m, k_simd, None, X0, T, steps)
            ns = _time_batch(cols, n, steps, budget)
            ratio = {c: ns["numpy"] / v for c, v in ns.items()}
            met += ratio["default"] >= 1.5
            total += 1
            cell = {c: f"{ns[c]:{w}.1f} {ratio[c]:5.2f}x" if c in ns else f"{'-':>{w}s} {'-':>6s}"
                    for c, w in (("1 thread", 8), ("map", 10), ("simd", 6))}
            line = (f"  {n:6d} {ns['numpy']:8.1f} {ns['default']:9.1f} {ratio['default']:5.2f}x "
                    f"{'yes' if ratio['default'] >= 1.5 else 'NO':>6s} {cell['1 thread']} "
                    f"{cell['map']} {cell['simd']}")
            if "simd" in ns:
                line += f" {np.abs(cols['simd']() - cols['default']()).max():9.1e}"
            print(line)
    print(f"target hybridnav >= 1.5x NumPy: met at {met} of {total} (model, batch) pairs; load "
          f"average {os.getloadavg()[0]:.2f} at the end")


if __name__ == "__main__":
    main()
