"""The certificate route: vectorized interval evaluation, and the proofs the README quotes.

Prints, measured in this run (best of 3 timings; the machine is shared, so read the ratios):

* interval evaluation of LbCS's ``L``, ``Ldot``, constraints and flow on 4096 boxes in one call vs
  4096 calls of one box each (the vectorization the branch and bound relies on);
* the branch and bound on LbCS (aco-local-minimum) at ``L <= 347``: boxes, time, boxes per second;
* LaSalle on the unicycle's polar error dynamics, and the quartic-plus-quadratic point-mass
  candidate: boxes and time.

Run: ``python benchmarks/bench_certificate.py``
"""

from __future__ import annotations

import math
import os
import time

import casadi as cs
import numpy as np

from hybridnav import models
from hybridnav.analysis import certify, lyapunov_functions
from hybridnav.analysis.interval import IntervalFunction
from hybridnav.analysis.region import Box, as_box
from hybridnav.world import load_scenario


def best(fn, repeat=3):
    times = []
    out = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def closed(model, target):
    return model.closed_loop_at(target)


def main() -> None:
    print(f"load average {os.getloadavg()[0]:.2f} (1 min)")
    scen = load_scenario("aco-local-minimum")
    lb = models.LbCS.from_scenario(scen)
    target = np.asarray(scen.robots[0].goal, dtype=float)
    _, V, Vdot, _, _ = lyapunov_functions(lb, target=target)
    f = closed(lb, target)
    g = cs.substitute(lb.state_constraints(), lb.sym.p, cs.DM(lb.p_value()))
    F = IntervalFunction(lb.sym.x, [V, Vdot, g, f])
    rng = np.random.default_rng(0)
    c = rng.uniform(10, 80, (4096, 2))
    w = rng.uniform(0.01, 1, (4096, 2))
    lo, hi = c - w, c + w
    t_batch, (bl, bh, _) = best(lambda: F(lo, hi))
    t_loop, rows = best(lambda: [F(lo[i:i + 1], hi[i:i + 1]) for i in range(len(lo))], repeat=1)
    same = all(np.array_equal(r[0][0], bl[i], equal_nan=True) for i, r in enumerate(rows))
    print(f"interval evaluation, LbCS (9 circles, {len(F._program)} instructions), 4096 boxes: "
          f"one call {t_batch * 1e3:.1f} ms, 4096 calls {t_loop * 1e3:.0f} ms: "
          f"{t_loop / t_batch:.0f}x; identical enclosures: {same}")

    region = as_box(lb, {"x": (10, 80), "y": (-10, 60)})
    t, cert = best(lambda: certify(lb.sym.x, f, V, region, level=347.0, constraints=g,
                                   center=target))
    print(f"LbCS on {{L <= 347}}: {cert.status}, {cert.boxes} boxes in {t:.2f} s "
          f"({cert.boxes / t:.0f} boxes/s), invariant {cert.invariant}")

    uni = models.get("unicycle")
    z, zdot, names = uni.polar_error_dynamics()
    zdot = cs.substitute(zdot, uni.sym.p, cs.DM(uni.p_value()))
    polar = Box(names, np.array([0.0, -math.pi]), np.array([5.0, math.pi]))
    t, cert = best(lambda: certify(z, zdot, 0.5 * z[0] ** 2, polar, lasalle=True))
    print(f"unicycle, LaSalle in (rho, e): {cert.status}, {cert.boxes} boxes in {t:.2f} s")

    pm = models.get("point_mass")
    tp = np.array([45.0, 5.0])
    d = pm.sym.x - cs.DM(tp)
    Vq = d[0] ** 4 + d[1] ** 4 + d[0] ** 2 + d[1] ** 2
    box = as_box(pm, {"x": (0, 50), "y": (0, 50)})
    t, cert = best(lambda: certify(pm.sym.x, closed(pm, tp), Vq, box, center=tp))
    print(f"point mass, dx^4 + dy^4 + dx^2 + dy^2 on [0, 50]^2: {cert.status}, {cert.boxes} "
          f"boxes in {t:.2f} s")


if __name__ == "__main__":
    main()
