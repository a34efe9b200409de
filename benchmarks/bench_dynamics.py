"""Tractor-trailer closed loop, 50 robots x 100 steps: hybridnav vs NumPy RK4 vs solve_ivp loop.

Prints times measured in this one run and their ratios (targets: hybridnav >= 3x faster than the
hand-written NumPy vectorized RK4, >= 100x faster than a Python loop of ``solve_ivp`` per robot).
Run: ``python benchmarks/bench_dynamics.py [--robots 50] [--steps 100] [--repeat 20]``.
"""

from __future__ import annotations

import argparse
import math
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


def numpy_rollout(X0, T, steps, h, q):
    out = np.empty((len(X0), steps + 1, X0.shape[1]))
    out[:, 0] = X = X0
    for k in range(steps):
        k1 = numpy_rhs(X, T, q)
        k2 = numpy_rhs(X + h / 2 * k1, T, q)
        k3 = numpy_rhs(X + h / 2 * k2, T, q)
        k4 = numpy_rhs(X + h * k3, T, q)
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
    q = m.params
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


if __name__ == "__main__":
    main()
