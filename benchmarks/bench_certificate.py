"""The certificate route: vectorized interval evaluation, and the verdicts, before and after.

Prints, measured in this run (best of 3 timings; the machine is shared, so read the ratios):

* interval evaluation of LbCS's ``L``, ``Ldot``, constraints and flow on 4096 boxes in one call vs
  one box per call (256 calls timed, scaled to 4096; the vectorization the branch and bound
  relies on);
* a table of verdicts — status, boxes, seconds, boxes per second — for the certificate's cases
  (LbCS at ``L <= 347``, LaSalle on the unicycle's polar error dynamics, the quartic-plus-quadratic
  point-mass candidate, the saturated point mass, reversed Van der Pol's Lyapunov-equation
  candidate at level 2.25, the softmax-blended system with an unstable equilibrium) and notebook
  01's ``estimate_roa`` of LbCS with the Lyapunov-equation candidate (timed once), for this
  tree and, with ``--before REV``, for the commit ``REV`` (a temporary ``git worktree``), side
  by side in one run with the time ratio.

Run: ``python benchmarks/bench_certificate.py [--before REV]``
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CASES = """
import json, math, time
import casadi as cs
import numpy as np
from hybridnav import models
from hybridnav.analysis import certify, lyapunov_functions
from hybridnav.analysis.region import Box, as_box
from hybridnav.models.base import Model
from hybridnav.world import load_scenario


def best(fn, repeat=3):
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


class Flow(Model):
    name = "flow"
    plant_state_names = ("x", "y")
    input_names = ("vx", "vy")
    parameters = {}
    rhs = None

    def open_loop(self, x, u, p):
        return cs.vertcat(u[0], u[1])

    def controller(self, x, t, p):
        return type(self).rhs(cs.vertcat(x[0] - t[0], x[1] - t[1]))


def flow(rhs):
    return type("F", (Flow,), {"rhs": staticmethod(rhs)})()


def run(name, make):
    t, cert = best(make)
    return {"case": name, "status": cert.status, "boxes": int(cert.boxes), "seconds": t}


out = []
scen = load_scenario("aco-local-minimum")
lb = models.LbCS.from_scenario(scen)
target = np.asarray(scen.robots[0].goal, dtype=float)
_, V, _, _, _ = lyapunov_functions(lb, target=target)
f = lb.closed_loop_at(target)
g = cs.substitute(lb.state_constraints(), lb.sym.p, cs.DM(lb.p_value()))
region = as_box(lb, {"x": (10, 80), "y": (-10, 60)})
out.append(run("LbCS, L <= 347", lambda: certify(lb.sym.x, f, V, region, level=347.0,
                                                 constraints=g, center=target)))
uni = models.get("unicycle")
z, zdot, names = uni.polar_error_dynamics()
zdot = cs.substitute(zdot, uni.sym.p, cs.DM(uni.p_value()))
polar = Box(names, np.array([0.0, -math.pi]), np.array([5.0, math.pi]))
out.append(run("unicycle, LaSalle (rho, e)",
               lambda: certify(z, zdot, 0.5 * z[0] ** 2, polar, lasalle=True)))
pm = models.get("point_mass")
tp = np.array([45.0, 5.0])
d = pm.sym.x - cs.DM(tp)
box = as_box(pm, {"x": (0, 50), "y": (0, 50)})
out.append(run("point mass, dx^4 + dy^4 + dx^2 + dy^2",
               lambda: certify(pm.sym.x, pm.closed_loop_at(tp),
                               d[0] ** 4 + d[1] ** 4 + d[0] ** 2 + d[1] ** 2, box, center=tp)))


def saturated(e):
    r = cs.sqrt(e[0] ** 2 + e[1] ** 2)
    s = cs.fmin(1, 1.0 / (0.5 * r + 1e-12))
    return cs.vertcat(-0.5 * e[0] * s, -0.5 * e[1] * s)


sp = flow(saturated)
out.append(run("saturated point mass (fmin)",
               lambda: certify(sp.sym.x, sp.closed_loop_at((45.0, 5.0)),
                               0.5 * cs.sumsqr(sp.sym.x - cs.DM([45.0, 5.0])), box,
                               center=np.array([45.0, 5.0]))))
vdp = flow(lambda e: cs.vertcat(-e[1], e[0] + (e[0] ** 2 - 1) * e[1]))
P = cs.DM([[1.5, -0.5], [-0.5, 1.0]])
xv = vdp.sym.x
out.append(run("reversed Van der Pol, V = x'Px <= 2.25",
               lambda: certify(xv, vdp.closed_loop_at((0.0, 0.0)), cs.bilin(P, xv, xv),
                               Box(("x", "y"), np.array([-3.0, -3.0]), np.array([3.0, 3.0])),
                               level=2.25, center=np.zeros(2))))


def softmax(e):
    w = cs.exp(100 * e[0]) / (cs.exp(100 * e[0]) + cs.exp(cs.SX(800.0)))
    return cs.vertcat(-e[0] + 2 * e[0] * w, -e[1])


sm = flow(softmax)
out.append(run("softmax blend, unstable x = 8 (must not be proved)",
               lambda: certify(sm.sym.x, sm.closed_loop_at((0.0, 0.0)),
                               0.5 * cs.sumsqr(sm.sym.x),
                               Box(("x", "y"), np.array([-10.0, -1.0]), np.array([10.0, 1.0])),
                               center=np.zeros(2), max_boxes=50_000)))
# the whole region-of-attraction estimate of notebook 01 (sampling, IPOPT, the certificate at
# the sampled level and the lowered ones): where a user waits in Jupyter; timed once
from hybridnav.analysis.roa import estimate_roa, lyapunov_equation_candidate

V_lyap, _ = lyapunov_equation_candidate(lb, scen.robots[0].goal)
t0 = time.perf_counter()
roa = estimate_roa(lb, V_lyap, target=scen.robots[0].goal, region={"x": (0, 50), "y": (0, 50)},
                   confirm=100)
out.append({"case": "estimate_roa, LbCS, Lyapunov-equation V (nb 01)",
            "status": f"{roa.status} at L = {roa.level:.6g}", "boxes": 0,
            "seconds": time.perf_counter() - t0})
print(json.dumps(out))
"""


def measure(root: Path) -> list[dict]:
    env = {**os.environ, "PYTHONPATH": str(root)}
    res = subprocess.run([sys.executable, "-c", CASES], env=env, capture_output=True,
                         text=True, cwd=tempfile.gettempdir())
    if res.returncode:
        raise SystemExit(f"the cases failed on {root}:\n{res.stderr[-3000:]}")
    return json.loads(res.stdout.strip().splitlines()[-1])


def interval_vectorization() -> None:
    import casadi as cs
    import numpy as np

    from hybridnav import models
    from hybridnav.analysis import lyapunov_functions
    from hybridnav.analysis.interval import IntervalFunction
    from hybridnav.world import load_scenario

    scen = load_scenario("aco-local-minimum")
    lb = models.LbCS.from_scenario(scen)
    target = np.asarray(scen.robots[0].goal, dtype=float)
    _, V, Vdot, _, _ = lyapunov_functions(lb, target=target)
    f = lb.closed_loop_at(target)
    g = cs.substitute(lb.state_constraints(), lb.sym.p, cs.DM(lb.p_value()))
    F = IntervalFunction(lb.sym.x, [V, Vdot, g, f])
    rng = np.random.default_rng(0)
    c = rng.uniform(10, 80, (4096, 2))
    w = rng.uniform(0.01, 1, (4096, 2))
    lo, hi = c - w, c + w
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        bl, _, _ = F(lo, hi)
        times.append(time.perf_counter() - t0)
    t_batch = min(times)
    k = 256                              # one-box calls timed (the rest scale linearly)
    t0 = time.perf_counter()
    rows = [F(lo[i:i + 1], hi[i:i + 1]) for i in range(k)]
    t_loop = (time.perf_counter() - t0) * len(lo) / k
    same = all(np.array_equal(r[0][0], bl[i], equal_nan=True) for i, r in enumerate(rows))
    print(f"interval evaluation, LbCS (9 circles, {len(F._program)} instructions), 4096 boxes: "
          f"one call {t_batch * 1e3:.1f} ms, one box per call {t_loop * 1e3:.0f} ms (from "
          f"{k} calls): {t_loop / t_batch:.0f}x; identical enclosures: {same}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", help="a git revision to measure beside this tree")
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f} (1 min)")
    interval_vectorization()
    here = Path(__file__).resolve().parents[1]
    after = measure(here)
    before = None
    if args.before:
        tmp = Path(tempfile.mkdtemp(prefix="bench_before_"))
        try:
            subprocess.run(["git", "-C", str(here), "worktree", "add", "--detach", str(tmp / "t"),
                            args.before], check=True, capture_output=True)
            before = measure(tmp / "t")
        finally:
            subprocess.run(["git", "-C", str(here), "worktree", "remove", "--force",
                            str(tmp / "t")], capture_output=True)
            shutil.rmtree(tmp, ignore_errors=True)
    head = f"{'case':52s} {'status':10s} {'boxes':>7s} {'s':>6s} {'boxes/s':>8s}"
    if before:
        head += f" | {'before':10s} {'boxes':>7s} {'s':>6s} {'boxes/s':>8s} {'speed-up':>10s}"
    print(head)
    for i, a in enumerate(after):
        line = (f"{a['case']:52s} {a['status']:10s} {a['boxes']:7d} {a['seconds']:6.2f} "
                f"{a['boxes'] / a['seconds']:8.0f}")
        if before:
            b = before[i]
            line += (f" | {b['status']:10s} {b['boxes']:7d} {b['seconds']:6.2f} "
                     f"{b['boxes'] / b['seconds']:8.0f} {b['seconds'] / a['seconds']:9.2f}x")
        print(line)


if __name__ == "__main__":
    main()
